"""SOFA (AES69) ``SingleRoomSRIR`` files as RIR banks, read lazily with h5py.

One file is one room (``RoomShortName``, else the file name without a ``_foa`` /
``_mic`` suffix). Used variables: ``Data.IR`` [M, R, N] (measurement, receiver,
sample), ``Data.SamplingRate``, ``SourcePosition`` [M or 1, 3] with its ``Type``
(``cartesian`` | ``spherical``) and ``Units`` (spherical: azimuth °, elevation °,
radius m; SOFA's frame is x front, y left, z up, azimuth counter-clockwise — ours),
``ListenerPosition`` and, if present, ``ListenerView`` / ``ListenerUp`` (the array's
+x and +z axes), so that a source at ``S`` is at ``R^T (S - L)`` in the array frame.

SpatialScaper's ``prepare_rirs.py`` writes ``<room>_{foa,mic}.sofa`` whose
``SourcePosition`` is already relative to the array while ``ListenerPosition`` holds
the array's position in the room; such files (recognised by their ``Organization`` /
``DatabaseName`` / ``Comment`` attributes) are read with ``SourcePosition`` as is.
Pass ``listener_relative=True/False`` to override the guess.

Format: ``format=`` if given, else ``ListenerShortName`` (``foa`` / ``mic``), else the
file-name suffix; ``mic`` means the DCASE tetrahedral format (``tetra``).

Trajectories: SOFA has no trajectory grouping. With ``grouping="auto"`` the file order
is used when it is a path: runs of neighbouring positions, split where a step is over
3x both its neighbours or changes height by more than ``ring_tol`` m, kept when they
average at least 10 positions (SpatialScaper stores each TAU trajectory and height in
path order, circles and lines alike). Otherwise positions are grouped into rings of
equal height and equal horizontal distance (gaps over ``ring_tol`` m split them), each
sorted by azimuth. ``grouping="rings"`` or ``"runs"`` forces one. Ids are ``"g{i}"``.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..acoustics.sofa import in_listener_frame, position
from ..core.geometry import cart_to_sph, sph_to_cart
from ..core.h5str import as_str
from ..errors import BankError
from ..receivers import canonical, receiver
from ._h5 import H5Pool, read_rows
from .base import Bank, Trajectory, check_format, check_rate
from .paths import angular_steps
from .tau import TAU_ROOM_NUMBERS

_SUFFIX = re.compile(r"_(foa|mic|tetra|mic4)$", re.IGNORECASE)
_SPATIALSCAPER = ("music and audio research lab", "tau-srir-db-sofa", "arni-srir-db-sofa", "metu-sparg")


class SofaBank(Bank):
    kind = "sofa"

    def __init__(self, path_or_files, format: str | None = None, listener_relative: bool | None = None,
                 grouping: str = "auto", ring_tol: float = 0.1):
        if isinstance(path_or_files, (list, tuple)):
            files = [Path(p) for p in path_or_files]
            self.source = ", ".join(map(str, files)) if len(files) < 4 else f"{files[0].parent} ({len(files)} SOFA files)"
        else:
            p = Path(path_or_files)
            files = sorted(p.glob("*.sofa")) if p.is_dir() else [p]
            self.source = str(p)
        if not files:
            raise BankError(f"{self.source}: no .sofa files")
        if grouping not in ("auto", "rings", "runs"):
            raise BankError(f"unknown SOFA grouping {grouping!r}; expected auto, rings or runs")
        self._h5 = H5Pool()
        infos = [self._scan(f, listener_relative) for f in files]
        want = check_format(format) if format else None
        if want is None:
            fmts = {i["format"] for i in infos}
            if None in fmts:
                bad = next(i["path"] for i in infos if i["format"] is None)
                raise BankError(f"{bad}: cannot tell the array format (no ListenerShortName, no _foa/_mic suffix); "
                               f"give it (--format foa|tetra|mic4, or format= in Python)")
            if len(fmts) > 1:
                raise BankError(f"{self.source}: holds {sorted(fmts)} RIRs; choose one (--format, or format= in Python)")
            want = fmts.pop()
        else:
            infos = [i for i in infos if i["format"] in (None, want)]
            if not infos:
                raise BankError(f"{self.source}: no {want} SOFA files")
        self.format = want
        self.channel_names = receiver(want).channels(n=infos[0]["channels"])
        fs = {i["fs"] for i in infos}
        if len(fs) > 1:
            raise BankError(f"{self.source}: SOFA files have different sample rates {sorted(fs)}; resample them to one")
        self.fs = fs.pop()
        for i in infos:
            if i["channels"] != len(self.channel_names):
                raise BankError(f"{i['path']}: {i['channels']} receivers, but {want} has {len(self.channel_names)} channels")
        self._rooms = {}
        for i in infos:
            if i["room"] in self._rooms:
                raise BankError(f"{i['path']}: room {i['room']!r} appears twice (also {self._rooms[i['room']]['path']})")
            i["trajectories"] = _group(i["room"], i.pop("positions"), grouping, ring_tol)
            self._rooms[i["room"]] = i
        self.rooms = list(self._rooms)

    def _scan(self, path: Path, listener_relative) -> dict:
        if not path.exists():
            raise BankError(f"SOFA file {path} not found")
        try:
            f = self._h5.get(path)
        except OSError:
            raise BankError(f"{path}: not a SOFA file (SOFA files are HDF5/netCDF-4)") from None
        if as_str(f.attrs.get("Conventions")) != "SOFA" or "Data.IR" not in f:
            raise BankError(f"{path}: not a SOFA file with impulse responses (no Conventions=SOFA / Data.IR)")
        conv = as_str(f.attrs.get("SOFAConventions"))
        ir = f["Data.IR"]
        if ir.ndim != 3:
            raise BankError(f"{path}: Data.IR has shape {ir.shape}; expected [M, R, N] ({conv or 'unknown conventions'})")
        M, R, _ = ir.shape
        if "Data.SamplingRate" not in f:
            raise BankError(f"{path}: no Data.SamplingRate")
        fs = check_rate(f["Data.SamplingRate"][()], f"{path}: Data.SamplingRate")
        src = position(f, "SourcePosition", M, path, BankError)
        if src is None:
            raise BankError(f"{path}: no SourcePosition; positions missing")
        lis = position(f, "ListenerPosition", M, path, BankError)
        lis = np.zeros((M, 3)) if lis is None else lis
        if listener_relative is None:
            tag = " ".join(as_str(f.attrs.get(k)) for k in ("Organization", "DatabaseName", "Comment")).lower()
            listener_relative = not any(s in tag for s in _SPATIALSCAPER)
        rel = src - lis if listener_relative else src
        rel = in_listener_frame(f, rel, M, path, BankError)
        az, el, dist = cart_to_sph(rel)
        room = as_str(f.attrs.get("RoomShortName")) or _SUFFIX.sub("", path.stem)
        listener = as_str(f.attrs.get("ListenerShortName")).lower()
        m = _SUFFIX.search(path.stem)
        fmt = listener if canonical(listener) else (m.group(1).lower() if m else None)
        return {
            "path": path,
            "room": room,
            "format": check_format(fmt) if fmt else None,
            "fs": fs,
            "channels": int(R),
            "positions": np.stack([az, el, dist], axis=-1),
            "number": TAU_ROOM_NUMBERS.get(room),
            "listener_relative": bool(listener_relative),
        }

    def room_info(self, room):
        self.check_room(room)
        r = self._rooms[room]
        info = {"file": r["path"].name, "listener_relative": r["listener_relative"]}
        if r["number"] is not None:
            info["number"] = r["number"]
        return info

    def trajectories(self, room):
        self.check_room(room)
        return [t for t, _ in self._rooms[room]["trajectories"]]

    def _read(self, room, traj, rows):
        r = self._rooms[room]
        rows_in_file = dict((t.id, m) for t, m in r["trajectories"])[traj.id][rows]
        order = np.argsort(rows_in_file)
        ds = self._h5.get(r["path"])["Data.IR"]
        data = read_rows(ds, np.sort(rows_in_file))
        out = np.empty_like(data)
        out[order] = data
        return out

    def close(self):
        self._h5.close()


def _group(room, pos: np.ndarray, grouping: str, tol: float):
    """[(Trajectory, row numbers in the file)] — see the module docstring."""
    M = len(pos)
    runs = _runs(pos, tol) if grouping in ("auto", "runs") else None
    if runs is not None and (grouping == "runs" or M / len(runs) >= 10):
        groups = runs
    else:
        groups = _rings(pos, tol)
    out = []
    for i, rows in enumerate(groups):
        p = pos[rows]
        kind = "circular" if _is_circular(p) else "linear"
        closed = False
        if kind == "circular" and len(p) >= 8:
            steps = angular_steps(p)
            med = float(np.median(steps[:-1]))
            closed = med > 0 and steps[-1] <= 2 * med and float(steps[:-1].sum()) > 300
        out.append((Trajectory(room, f"g{i}", kind, p, closed), np.asarray(rows, dtype=np.int64)))
    return out


def _runs(pos: np.ndarray, tol: float):
    """Split the file order where a step jumps (over 3x both neighbouring steps) or changes
    height by more than ``tol`` m: rings and lines are smooth at constant height. Steps are
    compared with their neighbours, not with one typical step, because along a line sampled
    every degree they grow steadily (as 1/cos² of the angle off its normal), and horizontal
    distance is no test either: along a line it changes by up to a whole step."""
    if len(pos) < 3:
        return [np.arange(len(pos))]
    xyz = sph_to_cart(pos[:, 0], pos[:, 1], pos[:, 2])
    d = np.diff(xyz, axis=0)
    jump = np.linalg.norm(d, axis=1)
    near = np.maximum(np.r_[jump[1], jump[:-1]], np.r_[jump[1:], jump[-2]])
    cut = np.nonzero((jump > np.maximum(3.0 * near, 1e-6)) | (np.abs(d[:, 2]) > tol))[0] + 1
    return [r for r in np.split(np.arange(len(pos)), cut)]


def _clusters(v: np.ndarray, tol: float):
    order = np.argsort(v, kind="stable")
    gaps = np.nonzero(np.diff(v[order]) > tol)[0] + 1
    return np.split(order, gaps)


def _rings(pos: np.ndarray, tol: float):
    xyz = sph_to_cart(pos[:, 0], pos[:, 1], pos[:, 2])
    groups = []
    for by_z in _clusters(xyz[:, 2], tol):
        r_h = np.hypot(xyz[by_z, 0], xyz[by_z, 1])
        for sub in _clusters(r_h, tol):
            rows = by_z[sub]
            groups.append(rows[np.argsort(pos[rows, 0], kind="stable")])
    return sorted(groups, key=lambda g: (round(float(xyz[g, 2].mean()), 3), round(float(np.hypot(xyz[g, 0], xyz[g, 1]).mean()), 3)))


def _is_circular(p: np.ndarray) -> bool:
    """Constant horizontal distance (within 5 %) over an azimuth span of 30° or more."""
    if len(p) < 3:
        return True
    xyz = sph_to_cart(p[:, 0], p[:, 1], p[:, 2])
    r_h = np.hypot(xyz[:, 0], xyz[:, 1])
    return bool(np.std(r_h) <= 0.05 * np.mean(r_h) and np.ptp(np.unwrap(np.radians(p[:, 0]))) >= np.radians(30))
