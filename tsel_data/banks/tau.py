"""TAU-SRIR DB, read in place as distributed (Politis, Adavanne, Virtanen, Zenodo 6408611).

Layout of the distribution directory ``TAU-SRIR_DB/``:

- ``rirdata.mat`` (MATLAB v5): struct ``rirdata`` with ``fs`` (24000) and ``room``, a
  struct array with one entry per room: its name, and ``rirs``, a struct array
  [trajectory × height] whose field ``doa_xyz`` is [nDOA × 3], the unit vectors from
  the array to each measured source position, in the order the source moved.
  Missing (trajectory, height) pairs are empty.
- ``measinfo.mat`` (MATLAB v5): struct array ``measinfo``, one entry per room, with
  ``room``, ``trajectories`` (group names), ``trajectoryType`` (``circular`` |
  ``linear``), ``distances``, ``heights`` (metres above the floor), ``micPosition``
  ([0, 0, 1.2]: coordinates have their origin on the floor below the array),
  ``dimensions``.
- ``rirs_NN_<room>.mat`` (MATLAB v7.3 = HDF5): struct array ``rirs`` [trajectory ×
  height] with fields ``mic`` and ``foa``, each [7200 samples × 4 channels × nDOA].
  In HDF5, MATLAB stores the struct array as group ``/rirs`` whose field datasets hold
  object references, with the dimensions reversed ([height, trajectory]); each
  reference points to a dataset whose dimensions are reversed too: [nDOA, 4, 7200].
  So one (trajectory, height) slice is one dataset, and RIR ``i`` of it is
  ``dset[i]`` — this reader reads exactly the rows it is asked for.

Conventions: ``doa_xyz`` is in the DCASE array frame (x front, y left, z up; the DCASE
generator turns it into azimuth with ``atan2(y, x)`` and elevation with
``atan2(z, hypot(x, y))``), which is this toolkit's frame, so positions are used as
they are. FOA is ACN/SN3D (W, Y, Z, X) and MIC is the Eigenmike tetrahedral subset,
both as in docs/format.md.

Distances are not in ``doa_xyz``. Circular rooms: ``distances`` is [1 × nGroups], the
horizontal radius of each group's circle around the vertical axis through the array,
so the distance is that radius over ``hypot(x, y)`` of the unit vector. Linear rooms
(sa203, sc203, se203, tb103): ``distances`` is [2 × 3 × nGroups], the start and end
points (x, y, z) of each group's line, which runs parallel to the array's y axis on one
side of it; the source lies on the vertical plane through that line, so the distance
is where the DOA ray meets the plane (SpatialScaper's cylinder about y gives the same
for such lines). If measinfo lacks a usable value the distance is NaN (azimuth and
elevation are still exact).

Room numbers (used for the DCASE/paper splits): 1 bomb_shelter, 2 gym, 3 pb132,
4 pc226, 5 sa203, 6 sc203, 8 se203, 9 tb103, 10 tc352, from the ``rirs_NN_`` prefix.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..core.geometry import cart_to_sph
from ..core.files import check_input
from ..errors import BankError
from ..receivers import receiver
from ._h5 import H5Pool, read_rows
from .base import Bank, Trajectory, check_format, check_rate
from .paths import angular_steps

TAU_ROOM_NUMBERS = {
    "bomb_shelter": 1, "gym": 2, "pb132": 3, "pc226": 4, "sa203": 5,
    "sc203": 6, "se203": 8, "tb103": 9, "tc352": 10,
}
_RIR_FILE = re.compile(r"^rirs_(\d+)_(.+)\.mat$")


# the DB's fields: the RIRs of the receivers it was measured with, named as those
# receivers' DCASE audio folders (ReceiverSpec.export_folder)
TAU_FIELDS = ("foa", "mic")
INDEX_FILE = "rirdata.mat"  # what makes a folder the TAU-SRIR DB


def is_tau_folder(path) -> bool:
    """Whether ``path`` is a TAU-SRIR DB folder as distributed."""
    return os.path.isfile(os.path.join(path, INDEX_FILE))


class TauBank(Bank):
    """The TAU-SRIR DB directory as distributed, read lazily with h5py.

    format: ``foa`` or ``mic``/``tetra``. Trajectory ids are ``"t{T}h{H}"`` (0-based
    trajectory and height of the measurement), one per non-empty (trajectory, height).
    """

    kind = "tau"

    def __init__(self, root, format: str = "foa"):
        import scipy.io  # slow to import (~0.2 s); only TAU banks need it

        self.root = Path(root)
        self.source = str(self.root)
        self.format = check_format(format, f"{root}: ")
        self._field = receiver(self.format).export_folder
        if self._field not in TAU_FIELDS:
            raise BankError(f"{root}: the TAU-SRIR DB holds foa and mic (tetra) RIRs, not {self.format}")
        self.channel_names = receiver(self.format).channel_names
        for name in ("rirdata.mat", "measinfo.mat"):
            check_input(self.root / name, BankError, "copy the TAU-SRIR DB again")  # a FIFO keeps loadmat waiting
            if not (self.root / name).exists():
                raise BankError(f"{self.root}: {name} not found; it ships with the TAU-SRIR DB (point at the TAU-SRIR_DB directory)")
        try:
            rd = scipy.io.loadmat(self.root / "rirdata.mat", struct_as_record=True, squeeze_me=False)["rirdata"][0, 0]
            mi = scipy.io.loadmat(self.root / "measinfo.mat", struct_as_record=True, squeeze_me=False)["measinfo"]
        except (KeyError, ValueError, OSError, NotImplementedError) as e:
            raise BankError(f"{self.root}: rirdata.mat/measinfo.mat are not the TAU-SRIR DB's ({e})") from None
        self.fs = check_rate(rd["fs"], f"{self.root}/rirdata.mat") if "fs" in rd.dtype.names else 24000
        entries = rd["room"].reshape(-1)
        meas = mi.reshape(-1)
        files = {}
        for p in sorted(self.root.glob("rirs_*.mat")):
            m = _RIR_FILE.match(p.name)
            if m:
                check_input(p, BankError, "copy the TAU-SRIR DB again")
                files[m.group(2)] = (int(m.group(1)), p)
        if not files:
            raise BankError(f"{self.root}: no rirs_NN_<room>.mat files; the RIRs of the TAU-SRIR DB are missing")

        self._rooms: dict[str, dict] = {}
        names = [_room_name(e) for e in entries]
        for name, (number, path) in sorted(files.items(), key=lambda kv: kv[1][0]):
            i = _match(name, names)
            if i is None:
                # DCASE order: entries follow the room numbers with 7 left out.
                order = sorted(TAU_ROOM_NUMBERS.values())
                i = order.index(number) if number in order and order.index(number) < len(entries) else None
            if i is None:
                raise BankError(f"{self.root}: rirdata.mat has no entry for {path.name}; rooms there are {names}")
            j = _match(names[i], [_room_name(m) for m in meas])
            if j is None:
                j = i if i < len(meas) else None
            self._rooms[name] = {
                "number": number,
                "path": path,
                "entry": entries[i],
                "meas": meas[j] if j is not None else None,
            }
        self.rooms = list(self._rooms)
        self._trajs: dict[str, list[Trajectory]] = {}
        self._slices: dict[str, dict] = {}
        self._dims: dict[str, tuple] = {}
        self._h5 = H5Pool()

    # --- metadata ------------------------------------------------------------------------
    def room_info(self, room):
        self.check_room(room)
        r = self._rooms[room]
        info = {"number": r["number"], "file": r["path"].name}
        m = r["meas"]
        if m is not None:
            # micPosition is [0, 0, height] in measinfo's own origin (the floor below the array)
            for key, name in (("dimensions", "dimensions"), ("mic_position", "micPosition")):
                if name in m.dtype.names:
                    v = np.asarray(m[name], dtype=np.float64).reshape(-1)
                    if v.size:
                        info[key] = v.round(4).tolist()
        return info

    def trajectories(self, room):
        self.check_room(room)
        if room not in self._trajs:
            self._trajs[room] = self._load_trajectories(room)
        return list(self._trajs[room])

    def _load_trajectories(self, room) -> list[Trajectory]:
        r = self._rooms[room]
        rirs = _field_of(r["entry"], "rirs", lambda v: v.dtype.names and "doa_xyz" in v.dtype.names)
        if rirs is None:
            raise BankError(f"{self.root}/rirdata.mat: room {room} has no rirs(.doa_xyz) field; positions missing")
        rirs = np.atleast_2d(rirs)
        kind, dists = _trajectory_geometry(r["meas"])
        out, slices = [], {}
        for t in range(rirs.shape[0]):
            for h in range(rirs.shape[1]):
                doa = np.asarray(rirs[t, h]["doa_xyz"], dtype=np.float64)
                if doa.size == 0:
                    continue
                doa = doa.reshape(-1, 3)
                az, el, _ = cart_to_sph(doa)
                dist = _distances(doa, kind, dists, t)
                tid = f"t{t}h{h}"
                pos = np.stack([az, el, dist], axis=-1)
                closed = kind == "circular" and _is_closed(pos)
                out.append(Trajectory(room, tid, kind, pos, closed))
                slices[tid] = (t, h)
        self._slices[room] = slices
        self._dims[room] = rirs.shape
        return out

    # --- RIRs ----------------------------------------------------------------------------
    def _dataset(self, room, traj):
        self.trajectories(room)
        f = self._h5.get(self._rooms[room]["path"])
        if "rirs" not in f:
            raise BankError(f"{self._rooms[room]['path']}: no struct 'rirs'; not a TAU-SRIR DB RIR file")
        g = f["rirs"]
        if self._field not in g:
            raise BankError(f"{self._rooms[room]['path']}: struct rirs has no field {self._field!r}")
        refs = g[self._field]
        t, h = self._slices[room][traj.id]
        n_traj, n_height = self._dims[room]
        # MATLAB writes a [trajectory x height] struct array as HDF5 [height, trajectory]
        # (as mat73 reads it). In a square room (se203 is 4 x 4) both tests below match;
        # the first, MATLAB's order, is the one real files use.
        if refs.shape == (n_height, n_traj):
            ref = refs[h, t]
        elif refs.shape == (n_traj, n_height):
            ref = refs[t, h]
        else:
            raise BankError(
                f"{self._rooms[room]['path']}: rirs.{self._field} is {refs.shape}, but rirdata.mat lists "
                f"{n_traj} trajectories x {n_height} heights for {room}"
            )
        return f[ref]

    def _read(self, room, traj, rows):
        ds = self._dataset(room, traj)
        n = len(traj)
        if ds.shape[0] == n:  # [nDOA, C, L]: MATLAB's reversed [L × C × nDOA]
            data = read_rows(ds, rows)
        elif ds.shape[-1] == n:  # written without reversal: [L, C, nDOA]
            data = np.moveaxis(ds[..., _selection(rows)], -1, 0).transpose(0, 2, 1)
        else:
            raise BankError(
                f"{self._rooms[room]['path']}: {room}/{traj.id} holds RIRs of shape {ds.shape}, "
                f"but rirdata.mat lists {n} positions"
            )
        return np.asarray(data, dtype=np.float32)

    def close(self):
        self._h5.close()


def _selection(rows: np.ndarray):
    """A slice when rows are contiguous (one hyperslab), else the sorted index list."""
    if len(rows) > 1 and rows[-1] - rows[0] == len(rows) - 1:
        return slice(int(rows[0]), int(rows[-1]) + 1)
    if len(rows) == 1:
        return slice(int(rows[0]), int(rows[0]) + 1)
    return rows.tolist()


def _text(v) -> str:
    a = np.asarray(v)
    if a.dtype.kind in "US":
        return "".join(str(x) for x in a.reshape(-1)).strip()
    if a.dtype == object and a.size:
        return _text(a.reshape(-1)[0])
    return ""


def _room_name(rec) -> str:
    names = rec.dtype.names or ()
    for key in ("name", "room", "roomName"):
        if key in names and _text(rec[key]):
            return _text(rec[key])
    for key in names:
        s = _text(rec[key])
        if s:
            return s
    return ""


def _match(name: str, names: list[str]):
    for i, n in enumerate(names):
        if n == name:
            return i
    for i, n in enumerate(names):
        if n and (n.startswith(name) or name.startswith(n)):
            return i
    return None


def _field_of(rec, name, pred):
    names = rec.dtype.names or ()
    if name in names:
        return rec[name]
    for key in names:
        v = rec[key]
        if isinstance(v, np.ndarray) and pred(v):
            return v
    return None


def _trajectory_geometry(meas):
    if meas is None:
        return "circular", None
    names = meas.dtype.names or ()
    kind = _text(meas["trajectoryType"]).lower() if "trajectoryType" in names else "circular"
    kind = "linear" if kind.startswith("lin") else "circular"
    dists = None
    if "distances" in names:
        v = meas["distances"]
        while isinstance(v, np.ndarray) and v.dtype == object and v.size == 1:
            v = v.reshape(-1)[0]
        try:
            dists = np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError):
            dists = None
    return kind, dists


def _distances(doa: np.ndarray, kind: str, dists, t: int) -> np.ndarray:
    nan = np.full(len(doa), np.nan)
    if dists is None or dists.size == 0:
        return nan
    if kind == "circular":
        d = dists.reshape(-1)
        if t >= d.size:
            return nan
        horiz = np.hypot(doa[:, 0], doa[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(horiz > 1e-6, d[t] / horiz, np.nan) * np.linalg.norm(doa, axis=1)
    # linear: [start, end] x (x, y, z) x group; intersect the ray with the vertical plane
    # through the group's line (horizontal coordinates are relative to the array)
    if dists.size % 6 or t >= dists.size // 6:
        return nan
    ends = dists.reshape(2, 3, -1)[:, :2, t]
    along = ends[1] - ends[0]
    normal = np.array([-along[1], along[0]])
    if not np.any(normal):
        return nan
    with np.errstate(divide="ignore", invalid="ignore"):
        facing = doa[:, :2] @ normal
        s = (ends[0] @ normal) / facing
        ok = (np.abs(facing) > 1e-3 * np.linalg.norm(normal)) & (s > 0)
        return np.where(ok, s * np.linalg.norm(doa, axis=1), np.nan)


def _is_closed(pos: np.ndarray) -> bool:
    """A ring whose last-to-first step is no longer than twice the median step."""
    if len(pos) < 8:
        return False
    steps = angular_steps(pos)
    med = float(np.median(steps[:-1]))
    span = float(np.sum(steps[:-1]))
    return med > 0 and steps[-1] <= 2.0 * med and span > 300.0
