"""RIR banks: TAU-SRIR DB and SOFA layouts, the native format, paths, CLI, errors."""
import subprocess
import sys

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from support.banks import make_sofa, make_tau_db
from tsel_data.banks import BankError, MemoryBank, Trajectory, bank_path_positions, open_bank, sample_bank_path, sample_bank_point
from tsel_data.banks.native import NativeBank, write_bank
from tsel_data.errors import TselError
from tsel_data.core.geometry import SOUND_SPEED, cart_to_sph, foa_gains, sph_to_cart
from tsel_data.dsp.timevarying import render_moving


@pytest.fixture(scope="module")
def tau_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("TAU-SRIR_DB")
    # a source at a known doa_xyz: (0.5, -0.5, 1/sqrt 2) is azimuth -45 deg (front-right), elevation 45 deg
    doas = {("bomb_shelter", 0, 0): np.array([[0.5, -0.5, np.sqrt(0.5)], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])}
    truth = make_tau_db(root, doas=doas)
    return root, truth


class ReadLog:
    """Records which rows of which h5py datasets are read (``__getitem__`` and ``read_direct``)."""

    def __init__(self, monkeypatch):
        self.calls = []
        get, direct = h5py.Dataset.__getitem__, h5py.Dataset.read_direct

        def spy_get(ds, key, *a, **kw):
            self.calls.append((ds.name, _rows(key, ds)))
            return get(ds, key, *a, **kw)

        def spy_direct(ds, dest, source_sel=None, dest_sel=None):
            self.calls.append((ds.name, _rows(source_sel, ds)))
            return direct(ds, dest, source_sel, dest_sel)

        from tsel_data.banks import _h5

        chunk = _h5.read_chunk

        def spy_chunk(ds, row, out):
            self.calls.append((ds.name, [row]))
            return chunk(ds, row, out)

        monkeypatch.setattr(h5py.Dataset, "__getitem__", spy_get)
        monkeypatch.setattr(h5py.Dataset, "read_direct", spy_direct)
        monkeypatch.setattr(_h5, "read_chunk", spy_chunk)

    def data_reads(self):
        """{dataset name: sorted rows read} for RIR datasets."""
        out = {}
        for n, rows in self.calls:
            if n.startswith("/#refs#") or n.endswith("Data.IR") or n.endswith("/rirs"):
                out.setdefault(n, set()).update(rows)
        return {n: sorted(r) for n, r in out.items()}


def _rows(key, ds):
    key = key[0] if isinstance(key, tuple) else key
    if key is None or key is Ellipsis:
        return list(range(ds.shape[0]))
    if isinstance(key, slice):
        return list(range(*key.indices(ds.shape[0])))
    return [int(k) for k in np.atleast_1d(key)]


# --- TAU-SRIR DB ---------------------------------------------------------------------------
def test_tau_rooms_numbers_and_positions(tau_dir):
    root, truth = tau_dir
    b = open_bank(root)
    assert b.kind == "tau" and b.format == "foa" and b.fs == 24000 and b.channel_names == ("W", "Y", "Z", "X")
    assert b.rooms == ["bomb_shelter", "se203"]
    assert b.resolve_room(8) == "se203" and b.resolve_room("1") == "bomb_shelter"
    t = b.trajectory("bomb_shelter", "t0h0")
    assert np.allclose(t.positions[0, :2], [-45.0, 45.0])  # front-right, up
    assert np.allclose(t.positions[1, :2], [90.0, 0.0])  # +y is left
    assert np.allclose(t.positions[2, 0], -180.0)  # behind, wrapped to [-180, 180)
    # circular trajectory of horizontal radius 1.5 m: distance = 1.5 / cos(el)
    assert np.allclose(t.positions[:, 2], 1.5 / np.cos(np.radians(t.positions[:, 1])))
    ring = b.trajectory("bomb_shelter", "t1h0")  # radius 2.5 m, 0.4 m below the array
    assert ring.kind == "circular" and ring.closed
    assert np.allclose(ring.positions[:, 1], np.degrees(np.arctan2(-0.4, 2.5)))
    assert np.allclose(ring.positions[:, 2], np.hypot(2.5, 0.4))
    # se203 is a linear room: lines parallel to y, in front (t0, x = 1.5) and behind (t1, x = -2.5)
    for tid, (tt, h) in (("t0h0", (0, 0)), ("t0h2", (0, 2)), ("t1h1", (1, 1))):
        line = b.trajectory("se203", tid)
        want = truth["se203"][(tt, h)]
        assert line.kind == "linear" and not line.closed
        assert np.allclose(line.positions[:, 2], want["dist"])
        assert np.allclose(np.abs(line.positions[:, 0]) < 90, tt == 0)
    # the empty (trajectory 1, height 2) of se203 is not a trajectory
    assert [tr.id for tr in b.trajectories("se203")] == ["t0h0", "t0h1", "t0h2", "t1h0", "t1h1"]


def test_tau_reads_exactly_the_requested_rirs(tau_dir, monkeypatch):
    root, truth = tau_dir
    for fmt, field in (("foa", "foa"), ("mic", "mic")):
        b = open_bank(root, format=fmt)
        assert b.format == ("foa" if fmt == "foa" else "tetra")
        b.trajectories("bomb_shelter")
        log = ReadLog(monkeypatch)
        x = b.read("bomb_shelter", "t1h1", [5, 2, 5])
        assert x.dtype == np.float32 and x.shape == (3, 4, 48)
        assert np.array_equal(x, truth["bomb_shelter"][(1, 1)][field][[5, 2, 5]])
        reads = log.data_reads()
        ref = h5py.File(root / "rirs_01_bomb_shelter.mat", "r")["rirs"][field][1, 1]
        name = h5py.File(root / "rirs_01_bomb_shelter.mat", "r")[ref].name
        assert reads == {name: [2, 5]}  # one dataset, only the two rows asked for
        monkeypatch.undo()
        b.close()


def test_tau_reading_one_trajectory_leaves_the_others_alone(tmp_path, monkeypatch):
    truth = make_tau_db(tmp_path, rooms=(("tc352", 10),), n_traj=2, heights=(0.0, 5.0, 10.0, 15.0), n_doa=90, L=256, empty=())
    b = open_bank(tmp_path, format="foa")
    b.trajectories("tc352")
    log = ReadLog(monkeypatch)
    x = b.read("tc352", "t1h3", np.arange(10, 20))
    assert np.array_equal(x, truth["tc352"][(1, 3)]["foa"][10:20])
    reads = log.data_reads()
    assert len(reads) == 1 and list(reads.values())[0] == list(range(10, 20))  # one dataset, those rows only


def test_tau_written_by_hdf5storage_loads(tmp_path):
    """A v7.3 struct array written by hdf5storage (MATLAB-compatible writer) reads the same."""
    import hdf5storage

    truth = make_tau_db(tmp_path, rooms=(("gym", 2),), n_traj=1, heights=(0.0, 10.0), n_doa=6, L=16, empty=())
    rec = np.empty((1, 2), dtype=[("mic", object), ("foa", object)])
    for h in range(2):
        # MATLAB's [L x 4 x nDOA]
        rec[0, h]["foa"] = np.transpose(truth["gym"][(0, h)]["foa"], (2, 1, 0)).astype(np.float64)
        rec[0, h]["mic"] = np.transpose(truth["gym"][(0, h)]["mic"], (2, 1, 0)).astype(np.float64)
    (tmp_path / "rirs_02_gym.mat").unlink()
    hdf5storage.savemat(str(tmp_path / "rirs_02_gym.mat"), {"rirs": rec}, format="7.3")
    b = open_bank(tmp_path)
    assert np.allclose(b.read("gym", "t0h1", [0, 4]), truth["gym"][(0, 1)]["foa"][[0, 4]])


def test_tau_errors(tau_dir, tmp_path):
    root, _ = tau_dir
    b = open_bank(root)
    with pytest.raises(BankError, match="rooms are bomb_shelter, se203"):
        b.trajectories("gym")
    with pytest.raises(BankError, match="no room 7"):
        b.resolve_room(7)
    with pytest.raises(BankError, match="out of range"):
        b.read("bomb_shelter", "t0h0", [3])
    (tmp_path / "rirdata.mat").write_bytes((root / "rirdata.mat").read_bytes())
    with pytest.raises(BankError, match="measinfo.mat not found"):
        open_bank(tmp_path)
    with pytest.raises(BankError, match="not found"):
        open_bank(tmp_path / "nope")
    with pytest.raises(BankError, match="give the TAU-SRIR DB directory"):
        open_bank(root / "rirdata.mat")
    (tmp_path / "x.h5").write_bytes(b"not hdf5")
    with pytest.raises(TselError):
        open_bank(tmp_path / "x.h5")


# --- SOFA ---------------------------------------------------------------------------------------
def _sofa_rings(n=16, els=(0.0, 20.0), r=1.5):
    """Array-relative positions of rings, stored ring after ring (path order)."""
    pos = np.concatenate([sph_to_cart(np.arange(n) * 360.0 / n - 180.0, el, r / np.cos(np.radians(el))) for el in els])
    return pos


def test_sofa_spatialscaper_file_loads_as_is(tmp_path, monkeypatch):
    pos = _sofa_rings()
    rirs = np.random.default_rng(0).standard_normal((len(pos), 4, 32))
    path = make_sofa(tmp_path / "bomb_shelter_foa.sofa", rirs, pos, room="bomb_shelter")
    b = open_bank(path)
    assert b.kind == "sofa" and b.format == "foa" and b.rooms == ["bomb_shelter"]
    assert b.room_info("bomb_shelter")["number"] == 1
    trajs = b.trajectories("bomb_shelter")
    assert len(trajs) == 2 and all(t.kind == "circular" and t.closed for t in trajs)
    az, el, dist = cart_to_sph(pos)
    assert np.allclose(trajs[1].positions, np.stack([az, el, dist], -1)[16:])  # ListenerPosition not subtracted
    log = ReadLog(monkeypatch)
    x = b.read("bomb_shelter", trajs[1].id, [3, 0])
    assert np.allclose(x, rirs[[16 + 3, 16 + 0]].astype(np.float32))
    assert list(log.data_reads().values()) == [[16, 19]]


def test_sofa_generic_listener_relative_with_view(tmp_path):
    pos = _sofa_rings(n=12, els=(10.0,))
    rirs = np.random.default_rng(1).standard_normal((len(pos), 4, 8))
    path = make_sofa(tmp_path / "room.sofa", rirs, pos, style="generic", listener=(3.0, 2.0, 1.5),
                     listener_view=(0.0, 1.0, 0.0), room="lab", listener_name="mic")
    b = open_bank(path)
    assert b.format == "tetra" and b.rooms == ["lab"]
    t = b.trajectories("lab")[0]
    az, el, dist = cart_to_sph(pos)
    order = np.argsort(az)
    assert np.allclose(np.sort(t.positions[:, 0]), az[order], atol=1e-6)
    assert np.allclose(t.positions[:, 1], 10.0) and np.allclose(t.positions[:, 2], dist)


def test_sofa_rings_grouping_for_unordered_files(tmp_path):
    pos = _sofa_rings(n=8, els=(0.0, 30.0))
    perm = np.random.default_rng(2).permutation(len(pos))
    rirs = np.arange(len(pos))[:, None, None] * np.ones((1, 4, 4))
    path = make_sofa(tmp_path / "r_foa.sofa", rirs[perm], pos[perm], room="r")
    b = open_bank(path)
    trajs = b.trajectories("r")
    assert len(trajs) == 2
    for t in trajs:
        assert np.all(np.diff(t.positions[:, 0]) > 0)  # sorted by azimuth
        got = b.read("r", t.id, np.arange(len(t)))[:, 0, 0]
        assert np.allclose(pos[got.astype(int)], sph_to_cart(*t.positions.T))  # RIR i belongs to position i


def test_sofa_lines_in_file_order_are_linear_trajectories(tmp_path):
    """SpatialScaper's files of TAU's linear rooms: lines parallel to y on both sides of the
    array at three heights, 1 degree apart, every other line stored the other way round."""
    lines = []
    for k, (x, z) in enumerate([(x, z) for x in (1.5, -2.5) for z in (-0.4, 0.0, 0.4)]):
        y = abs(x) * np.tan(np.radians(np.arange(-65.0, 65.5, 1.0)))
        lines.append(np.stack([np.full(len(y), x), y[:: -1 if k % 2 else 1], np.full(len(y), z)], -1))
    pos = np.concatenate(lines)
    rirs = np.arange(len(pos))[:, None, None] * np.ones((1, 4, 4))
    b = open_bank(make_sofa(tmp_path / "se203_foa.sofa", rirs, pos, room="se203"))
    trajs = b.trajectories("se203")
    assert len(trajs) == 6
    start = 0
    for t, line in zip(trajs, lines):
        assert t.kind == "linear" and not t.closed and len(t) == len(line)
        want = cart_to_sph(line)
        assert np.allclose(t.positions[:, 0], want[0]) and np.allclose(t.positions[:, 2], want[2])
        assert np.array_equal(b.read("se203", t.id, [0, len(t) - 1])[:, 0, 0], [start, start + len(t) - 1])
        start += len(t)
    # a walk stays on its line: consecutive knots are neighbours, never a jump across the array
    rng = np.random.default_rng(0)
    for _ in range(20):
        tid, idx, times = sample_bank_path(b, "se203", rng, 10.0, 40.0)
        assert np.all(np.abs(np.diff(idx)) <= 4)


def test_sofa_errors(tmp_path):
    pos = _sofa_rings(n=8, els=(0.0,))
    rirs = np.zeros((8, 4, 4))
    a = make_sofa(tmp_path / "a_foa.sofa", rirs, pos, fs=24000, room="a")
    c = make_sofa(tmp_path / "c_foa.sofa", rirs, pos, fs=48000, room="c")
    with pytest.raises(BankError, match="different sample rates"):
        open_bank([a, c])
    bad = make_sofa(tmp_path / "bad_foa.sofa", rirs, pos, with_source=False)
    with pytest.raises(BankError, match="positions missing"):
        open_bank(bad)
    with pytest.raises(BankError, match="not found"):
        open_bank([tmp_path / "missing.sofa"])
    with pytest.raises(BankError, match="24000 Hz but the scenes are at 16000 Hz"):
        open_bank(a).require_fs(16000)


# --- native format, import, build, CLI ------------------------------------------------------
def test_import_tau_to_native_round_trip(tau_dir, tmp_path):
    from tsel_data.cli.bank import bank

    root, truth = tau_dir
    out = tmp_path / "tau.h5"
    res = CliRunner().invoke(bank, ["import", "tau", "--src", str(root), "--out", str(out), "--rooms", "8", "--format", "mic"])
    assert res.exit_code == 0, res.output
    nb = open_bank(out)
    assert isinstance(nb, NativeBank) and nb.format == "tetra" and nb.rooms == ["se203"] and nb.room_info("se203")["number"] == 8
    src = open_bank(root, format="mic")
    for t in src.trajectories("se203"):
        u = nb.trajectory("se203", t.id)
        assert u.kind == t.kind and u.closed == t.closed and np.allclose(u.positions, t.positions)
        assert np.array_equal(nb.read("se203", t.id, [len(t) - 1, 0]), truth["se203"][(int(t.id[1]), int(t.id[3]))]["mic"][[len(t) - 1, 0]])
    with h5py.File(out, "r") as f:
        d = f["rooms/se203/rirs"]
        assert d.dtype == np.float32 and d.chunks == (1, 4, 48)
        assert "importer" in f.attrs["provenance"]
    res = CliRunner().invoke(bank, ["info", str(out), "--trajectories"])
    assert res.exit_code == 0 and "se203 #8: " in res.output and "t1h1: linear, 24 RIRs" in res.output


def test_import_sofa_cli(tmp_path):
    from tsel_data.cli.bank import bank

    pos = _sofa_rings(n=8)
    files = [make_sofa(tmp_path / f"{r}_foa.sofa", np.ones((16, 4, 4)) * i, pos, room=r) for i, r in enumerate(("gym", "tc352"))]
    out = tmp_path / "s.h5"
    res = CliRunner().invoke(bank, ["import", "sofa", *map(str, files), "--out", str(out)])
    assert res.exit_code == 0, res.output
    nb = open_bank(out)
    assert nb.rooms == ["gym", "tc352"] and nb.resolve_room(10) == "tc352"
    assert np.all(nb.read("tc352", "g0", [1]) == 1.0)


def test_native_is_deterministic_and_lazy(tmp_path, monkeypatch):
    bank = _gain_bank()
    a, b = write_bank(tmp_path / "a.h5", bank), write_bank(tmp_path / "b.h5", bank)
    assert a.read_bytes() == b.read_bytes()
    nb = open_bank(a)
    log = ReadLog(monkeypatch)
    nb.read("room", 0, [7, 3])
    assert list(log.data_reads().values()) == [[3, 7]]


def test_build_demo_bank_cli(tmp_path):
    from tsel_data.cli.bank import bank

    out = tmp_path / "demo.h5"
    res = CliRunner().invoke(bank, ["build", "--out", str(out), "--demo", "--format", "foa", "--seed", "3"])
    assert res.exit_code == 0, res.output
    b = open_bank(out)
    assert b.format == "foa" and len(b.rooms) == 4  # the demo-moving preset's bank
    trajs = b.trajectories(b.rooms[0])
    assert len(trajs) == 4 and all(t.kind == "circular" and t.closed and len(t) == 36 for t in trajs)
    # the FOA direct path points where the bank says: first peak of W, and Y/W, X/W there
    t = trajs[0]
    h = b.read(b.rooms[0], t.id, [9, 27])  # azimuth -90 and +90
    for rir, (az, el, dist) in zip(h, t.positions[[9, 27]]):
        n = int(np.argmax(np.abs(rir[0])))
        assert abs(n - dist / SOUND_SPEED * b.fs) < 3
        g = rir[:, n] / rir[0, n]
        assert np.allclose(g, foa_gains(az, el), atol=0.05)


@pytest.mark.parametrize("args,needle", [
    (["--rt60", "0.8,0.3"], "0 < lo <= hi"), (["--fs", "0"], "must be >= 8000 and <= 192000 Hz"),
    (["--step", "400"], "must be > 0 and <= 90 deg"),
    (["--demo", "--step", "3"], "drop --step or --demo"), (["--rir-seconds", "-1"], "must be > 0 and <= 60 s"),
    (["--demo", "--rir-seconds", "0.00001"], "at least one sample"), (["--distances", "nan"], "must be finite"),
    (["--side", "-1"], "must be > 0 and <= 10 m, got -1.0"),
])
def test_build_rejects_bad_options(tmp_path, args, needle):
    small = [] if "--demo" in args else ["--rooms", "1"]
    r = subprocess.run([sys.executable, "-c", "from tsel_data.cli import main; main()", "bank", "build",
                        "--out", str(tmp_path / "b.h5"), *small, *args], capture_output=True, text=True)
    assert r.returncode == 2 and needle in r.stderr and "Traceback" not in r.stderr and len(r.stderr.splitlines()) == 1
    assert not (tmp_path / "b.h5").exists()


# --- paths and labels ---------------------------------------------------------------------------
def _gain_bank(n=72, L=16):
    """One room, one closed ring and one open line; RIR k = FOA gains of position k (no delay)."""
    az = np.arange(n) * 360.0 / n - 180.0
    ring = np.stack([az, np.zeros(n), np.full(n, 2.0)], -1)
    line = np.stack([np.linspace(-60, 60, 25), np.full(25, 5.0), np.full(25, 1.5)], -1)
    items = []
    for tid, pos, kind, closed in ((0, ring, "circular", True), (1, line, "linear", False)):
        h = np.zeros((len(pos), 4, L), dtype=np.float32)
        h[:, :, 0] = foa_gains(pos[:, 0], pos[:, 1])
        items.append((Trajectory("room", tid, kind, pos, closed), h))
    return MemoryBank(8000, "foa", {"room": items})


@pytest.mark.parametrize("speed", [10.0, 20.0, 40.0, 90.0])
def test_bank_path_moves_at_the_drawn_speed(speed):
    bank = _gain_bank()
    for seed in range(6):
        rng = np.random.default_rng(seed)
        tid, idx, times = sample_bank_path(bank, "room", rng, 10.0, speed, trajectory=0)
        assert times[0] <= 0 <= 10.0 <= times[-1] and np.all(np.diff(times) > 0)
        assert np.all(np.diff(times) <= 0.1 + 1e-9) or speed * 0.1 < 5.0  # a knot at least every 100 ms
        t = bank.trajectory("room", tid)
        p = bank_path_positions(t, idx, times, np.arange(0, 10.0, 0.1) + 0.05)
        step = np.diff(np.degrees(np.unwrap(np.radians(p[:, 0]))))
        assert np.allclose(np.abs(step), speed * 0.1, atol=1e-6)  # constant angular speed, one direction
        assert np.allclose(bank_path_positions(t, idx, times, times), t.positions[idx])  # knots are bank positions


def test_open_path_turns_back_when_too_short():
    bank = _gain_bank()
    tid, idx, times = sample_bank_path(bank, "room", np.random.default_rng(0), 10.0, 40.0, trajectory=1)
    t = bank.trajectory("room", tid)
    assert idx.min() >= 0 and idx.max() < len(t)
    p = bank_path_positions(t, idx, times, np.linspace(0, 10, 201))
    assert np.all(p[:, 0] >= -60 - 1e-9) and np.all(p[:, 0] <= 60 + 1e-9)
    # great-circle speed (the line is at 5 deg elevation), constant except at the turns
    from tsel_data.banks.paths import angular_steps

    speed = angular_steps(p)[:-1] / 0.05
    assert np.median(speed) == pytest.approx(40.0, rel=1e-3)
    turns = np.nonzero(np.diff(np.sign(np.diff(p[:, 0]))))[0]
    assert len(turns) >= 2  # 400 deg of walk on a 120 deg line: it turns back


def test_static_point_and_render_follow_the_bank():
    bank = _gain_bank()
    rng = np.random.default_rng(7)
    tid, i = sample_bank_point(bank, "room", rng)
    assert 0 <= i < len(bank.trajectory("room", tid))
    tid, idx, times = sample_bank_path(bank, "room", rng, 2.0, 20.0, trajectory=0)
    x = rng.standard_normal(16000).astype(np.float32)
    y = render_moving(x, bank.read("room", tid, idx), times, bank.fs)[:, :16000]
    frames = y.reshape(4, 20, 800)
    measured = np.degrees(np.arctan2((frames[0] * frames[1]).sum(-1), (frames[0] * frames[3]).sum(-1)))
    labels = bank_path_positions(bank.trajectory("room", tid), idx, times, (np.arange(20) + 0.5) * 0.1)
    assert np.max(np.abs((measured - labels[:, 0] + 180) % 360 - 180)) < 1.0


def test_native_views_are_the_file_mapped_read_only_and_equal_read(tmp_path, monkeypatch):
    bank = _gain_bank()
    bank._rooms["room"].rirs[0] += np.arange(16, dtype=np.float32)  # distinct samples, not just gains
    nb = open_bank(write_bank(tmp_path / "b.h5", bank))
    nb.views("room", 0, [0])  # maps the file, checking the map against an HDF5 read of two rows
    log = ReadLog(monkeypatch)
    idx = [5, 71, 0, 5]
    views = nb.views("room", 0, idx)
    assert log.data_reads() == {}  # no HDF5 read of RIR data: the rows are views of a map
    want = bank.read("room", 0, idx)
    assert len(views) == 4 and all(np.array_equal(v, w) for v, w in zip(views, want))
    assert not views[0].flags.writeable
    line = nb.views("room", 1, [24])  # the second trajectory starts at its own offset in the file
    assert np.array_equal(line[0], bank.read("room", 1, [24])[0])
    nb.close()
    assert np.array_equal(views[1], want[1])  # views outlive the bank that gave them
    with pytest.raises(BankError, match="out of range"):
        nb.views("room", 0, [72])


def test_views_fall_back_to_reading_where_the_file_cannot_be_mapped(tmp_path):
    from tsel_data.banks._h5 import map_rows

    data = np.random.default_rng(0).standard_normal((6, 4, 32)).astype(np.float32)
    with h5py.File(tmp_path / "x.h5", "w") as f:
        f.create_dataset("plain", data=data)
        f.create_dataset("chunked", data=data, chunks=(1, 4, 32))
        f.create_dataset("gzip", data=data, chunks=(1, 4, 32), compression="gzip")
        f.create_dataset("f64", data=data.astype(np.float64))
    with h5py.File(tmp_path / "x.h5", "r") as f:
        for name in ("plain", "chunked"):
            rows = map_rows(tmp_path / "x.h5", f[name])
            assert len(rows) == 6 and all(np.array_equal(rows[i], data[i]) for i in range(6))
        assert map_rows(tmp_path / "x.h5", f["gzip"]) is None
        assert map_rows(tmp_path / "x.h5", f["f64"]) is None
    mem = _gain_bank()  # no file: views are reads
    assert all(np.array_equal(v, w) for v, w in zip(mem.views("room", 1, [3, 4]), mem.read("room", 1, [3, 4])))


def test_pickled_native_bank_maps_again(tmp_path):
    import pickle

    nb = open_bank(write_bank(tmp_path / "b.h5", _gain_bank()))
    v = nb.views("room", 0, [9])[0]
    nb2 = pickle.loads(pickle.dumps(nb))  # what a worker process receives
    assert np.array_equal(nb2.views("room", 0, [9])[0], v)


def test_damaged_bank_file_is_named(tmp_path):
    make_tau_db(tmp_path, rooms=(("gym", 2),), n_traj=1, heights=(1.2,), n_doa=8, L=4096, empty=())
    path = tmp_path / "rirs_02_gym.mat"
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])  # an interrupted download
    b = open_bank(tmp_path)
    assert len(b.trajectories("gym")) == 1  # metadata lives in rirdata.mat: still fine
    with pytest.raises(BankError, match=r"rirs_02_gym.mat: cannot be read as HDF5 \(truncated.*download it again"):
        b.read("gym", "t0h0", [0])
