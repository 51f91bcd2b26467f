"""Implausible banks are refused, not trusted (issue 24 §2, docs/reliability.md): positions
in millimetres or scaled by 10^6, outside the room, a sample rate of NaN, 0 or text,
RIRs with another format's channels, fewer RIRs than positions, a room info that is not
JSON, 1-D RIRs. `tsel check` (a config with the bank) and `tsel bank import` say each in
one line naming the room; nothing says "set fs = 0"."""
import h5py
import numpy as np
import pytest

from support.banks import make_native_bank, make_sofa, make_tau_db


def _rewrite(path, name, data):
    with h5py.File(path, "a") as f:
        g = f["rooms/roomA"]
        del g[name]
        g.create_dataset(name, data=data)


def _scale_positions(factor, columns):
    def damage(path):
        with h5py.File(path, "a") as f:
            p = f["rooms/roomA/positions"]
            x = p[()]
            x[:, columns] *= factor
            p[...] = x
    return damage


def _set_attr(name, value, room=False):
    def damage(path):
        with h5py.File(path, "a") as f:
            (f["rooms/roomA"] if room else f).attrs[name] = value
    return damage


def _rirs(fn):
    def damage(path):
        with h5py.File(path, "r") as f:
            rirs = f["rooms/roomA/rirs"][()]
        _rewrite(path, "rirs", fn(rirs))
    return damage


# case -> (damage, what the one line must say); every line names the bank's room roomA
DAMAGE = {
    "millimetres": (_scale_positions(1000.0, [2]), ["room roomA", "1500 m from the array", "7.5 x 6 x 3 m",
                                                     "millimetres"]),
    "scaled-1e6": (_scale_positions(1e6, [0, 1, 2]), ["room roomA", "not angles in degrees", "scaled"]),
    "outside-the-room": (_set_attr("info", '{"dims": [7.5, 6.0, 3.0], "array": {"centre": [0.5, 3.0, 1.2], '
                                           '"yaw": 0.0, "side": 0.11}}', room=True),
                         ["room roomA", "outside the room", "array at [0.5, 3.0, 1.2]"]),
    "three-channels": (_rirs(lambda r: r[:, :3]), ["room roomA", "3 channels", "mic4 bank's have 4"]),
    "rir-count": (_rirs(lambda r: r[:-1]), ["room roomA", "35 RIRs for 36 positions"]),
    "info-json": (_set_attr("info", "{not json", room=True), ["room roomA", "info is not JSON"]),
    "one-d-rirs": (_rirs(lambda r: r.reshape(-1)), ["room roomA", "RIRs of shape", "[N, channels, samples]"]),
}
RATES = {"nan": np.nan, "zero": 0, "text": "24 kHz"}


def _check(tsel_cli, demo_corpus, bank) -> str:
    return tsel_cli.refused("check", "--preset", "demo", "--corpus-dir", demo_corpus, "--bank", bank, "--no-plan",
                     "--split", "train=2", "--split", "val=0", "--split", "test=0", "--set", "audio.duration=1.0")


def test_a_plausible_bank_passes(tmp_path, tsel_cli, demo_corpus):
    bank = make_native_bank(tmp_path / "b.h5")
    code, _, err = tsel_cli.run("check", "--preset", "demo", "--corpus-dir", demo_corpus, "--bank", bank, "--no-plan",
                       "--split", "train=2", "--split", "val=0", "--split", "test=0", "--set", "audio.duration=1.0")
    assert code == 0, err


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_check_refuses_an_implausible_bank_naming_the_room(case, tmp_path, tsel_cli, demo_corpus):
    bank = make_native_bank(tmp_path / "b.h5")
    damage, needles = DAMAGE[case]
    damage(bank)
    line = _check(tsel_cli, demo_corpus, bank)
    for n in needles:
        assert n in line, (n, line)


@pytest.mark.parametrize("rate", sorted(RATES))
def test_a_rate_that_is_no_rate_is_one_line_and_never_set_fs_0(rate, tmp_path, tsel_cli, demo_corpus):
    bank = make_native_bank(tmp_path / "b.h5")
    _set_attr("fs", RATES[rate])(bank)
    for line in (_check(tsel_cli, demo_corpus, bank), tsel_cli.refused("bank", "info", bank)):
        assert "the sample rate is" in line and "not a rate in Hz" in line and "set fs" not in line, line


def test_import_refuses_sofa_positions_in_millimetres(tmp_path, tsel_cli):
    rng = np.random.default_rng(1)
    pos = 1.5 * np.stack([np.cos(np.linspace(0, 6, 12)), np.sin(np.linspace(0, 6, 12)), np.zeros(12)], axis=1)
    sofa = make_sofa(tmp_path / "hall_foa.sofa", rng.standard_normal((12, 4, 32)), pos * 1000.0, room="hall")
    line = tsel_cli.refused("bank", "import", "sofa", sofa, "--out", tmp_path / "b.h5")
    assert "room hall" in line and "1500 m from the array" in line and "millimetres" in line, line
    assert not (tmp_path / "b.h5").exists()


@pytest.mark.parametrize("rate", [0.0, np.nan])
def test_import_refuses_a_sofa_rate_that_is_no_rate(rate, tmp_path, tsel_cli):
    rng = np.random.default_rng(1)
    pos = np.stack([np.full(4, 1.5), np.arange(4.0) - 1.5, np.zeros(4)], axis=1)
    sofa = make_sofa(tmp_path / "hall_foa.sofa", rng.standard_normal((4, 4, 32)), pos, fs=rate, room="hall")
    line = tsel_cli.refused("bank", "import", "sofa", sofa, "--out", tmp_path / "b.h5")
    assert "hall_foa.sofa: Data.SamplingRate: the sample rate is" in line and "set fs" not in line, line


def test_import_refuses_tau_distances_in_millimetres(tmp_path, tsel_cli):
    make_tau_db(tmp_path / "tau", rooms=(("bomb_shelter", 1),), dists=(1500.0, 2500.0))
    line = tsel_cli.refused("bank", "import", "tau", "--src", tmp_path / "tau", "--out", tmp_path / "b.h5")
    assert "room bomb_shelter" in line and "m from the array, but the room is 8 x 6 x 3 m" in line, line
    assert not (tmp_path / "b.h5").exists()


def test_import_keeps_what_a_plausible_bank_holds(tmp_path, tsel_cli):
    """The refusals cost nothing to a good bank: the fixture DB imports as before."""
    make_tau_db(tmp_path / "tau", rooms=(("bomb_shelter", 1),))
    code, out, err = tsel_cli.run("bank", "import", "tau", "--src", tmp_path / "tau", "--out", tmp_path / "b.h5")
    assert code == 0 and "wrote" in out, err
