"""The toolkit's own RIR bank format (HDF5), see docs/banks.md.

    /                      attrs: tsel_bank (format version, 1), fs, format,
                           channel_names (JSON), provenance (JSON)
    /rooms/<room>/rirs     float32 [N, C, L], one chunk per RIR; RIRs of a trajectory
                           are contiguous, in path order
    /rooms/<room>/positions float64 [N, 3]: azimuth °, elevation °, distance m (array frame)
    /rooms/<room>/traj_ids, traj_kinds (str [T]), traj_closed (bool [T]),
                  traj_offsets (int64 [T + 1]): trajectory t is rows offsets[t]:offsets[t+1]
    /rooms/<room>          attrs: info (JSON: number, dims, provenance of the room)

Written under a temporary name and renamed, with ``track_times=False`` so the same
content gives the same bytes.
"""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import h5py
import numpy as np

from ..core.atomic import write_error
from ..core.files import check_input, is_regular
from ..core.h5str import as_str, as_strs
from ..errors import BankError, WriteError, shown_path
from ._h5 import H5Pool, read_rows
from .base import Bank, Trajectory, check_format, check_rate
from .plausible import positions_problem, rirs_problem

VERSION = 1


def is_native_bank(path) -> bool:
    if not is_regular(path):
        return False
    try:
        with h5py.File(path, "r") as f:
            return "tsel_bank" in f.attrs
    except OSError:
        return False


class NativeBank(Bank):
    kind = "native"

    def __init__(self, path):
        self.path = Path(path)
        self.source = str(self.path)
        if not self.path.exists():
            raise BankError(f"RIR bank {self.path} not found")
        check_input(self.path, BankError, "give the bank file itself")
        try:
            f = h5py.File(self.path, "r")
        except OSError:
            raise BankError(f"{self.path}: not an HDF5 file; expected a tsel RIR bank") from None
        with f:
            if "tsel_bank" not in f.attrs:
                raise BankError(f"{self.path}: not a tsel RIR bank (no tsel_bank attribute); convert with `tsel bank import`")
            if int(f.attrs["tsel_bank"]) > VERSION:
                raise BankError(f"{self.path}: bank format version {int(f.attrs['tsel_bank'])} is newer than this toolkit reads ({VERSION})")
            self.fs = check_rate(f.attrs.get("fs"), str(self.path))
            self.format = check_format(as_str(f.attrs.get("format", "")), f"{self.path}: ")
            self.channel_names = tuple(_json_attr(f.attrs, "channel_names", list, str(self.path)))
            self.provenance = _json_attr(f.attrs, "provenance", dict, str(self.path), "{}")
            self.rooms = list(f["rooms"].keys()) if "rooms" in f else []
            self._meta = {r: _room_meta(f["rooms"][r], r, f"{self.path}: room {r}") for r in self.rooms}
        self._h5 = H5Pool()

    def trajectories(self, room):
        self.check_room(room)
        return list(self._meta[room]["trajectories"])

    def room_info(self, room):
        self.check_room(room)
        return dict(self._meta[room]["info"])

    def _read(self, room, traj, rows):
        ds = self._h5.get(self.path)["rooms"][room]["rirs"]
        return read_rows(ds, rows + self._meta[room]["offset"][str(traj.id)])

    def _mapped(self, room, traj):
        rows = self._h5.mapped(self.path, f"rooms/{room}/rirs")
        if rows is None:
            return None
        a = self._meta[room]["offset"][str(traj.id)]
        return rows[a : a + len(traj)]

    def close(self):
        self._h5.close()


DAMAGED = "the bank is damaged: re-import or rebuild it"
ROOM_DATASETS = ("rirs", "positions", "traj_ids", "traj_kinds", "traj_offsets")


def _room_meta(g, room: str, where: str) -> dict:
    """A room's trajectories and info, once its datasets are known to fit together (each
    problem one BankError naming the room: render would crash on it, or read the wrong RIRs)."""
    for name in ROOM_DATASETS:
        if name not in g:
            raise BankError(f"{where} lacks {name}; the bank is incomplete")
    rirs = g["rirs"]
    if rirs.ndim != 3:
        raise BankError(f"{where}: RIRs of shape {rirs.shape}, expected [N, channels, samples]; {DAMAGED}")
    try:
        pos = np.asarray(g["positions"][()], dtype=np.float64)
        off = np.asarray(g["traj_offsets"][()], dtype=np.int64).reshape(-1)
    except (TypeError, ValueError):
        raise BankError(f"{where}: positions or traj_offsets are not numbers; {DAMAGED}") from None
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise BankError(f"{where}: positions of shape {pos.shape}, expected [N, 3] (azimuth, elevation, distance); "
                        f"{DAMAGED}")
    if rirs.shape[0] != len(pos):
        raise BankError(f"{where}: {rirs.shape[0]} RIRs for {len(pos)} positions; {DAMAGED}")
    ids, kinds = as_strs(g["traj_ids"][()]), as_strs(g["traj_kinds"][()])
    closed = (np.asarray(g["traj_closed"][()], dtype=bool).reshape(-1) if "traj_closed" in g
              else np.zeros(len(ids), bool))
    if (len(off) != len(ids) + 1 or len(kinds) != len(ids) or len(closed) != len(ids) or off[0] != 0
            or off[-1] != len(pos) or np.any(np.diff(off) < 0)):
        raise BankError(f"{where}: its {len(ids)} trajectories (traj_ids, traj_kinds, traj_closed, traj_offsets "
                        f"{off.tolist()[:4]}{'...' if len(off) > 4 else ''}) do not cover its {len(pos)} positions; "
                        f"{DAMAGED}")
    return {
        "trajectories": [Trajectory(room, ids[t], kinds[t], pos[off[t]: off[t + 1]], bool(closed[t]))
                         for t in range(len(ids))],
        "offset": {ids[t]: int(off[t]) for t in range(len(ids))},
        "info": _json_attr(g.attrs, "info", dict, where, "{}"),
    }


def _json_attr(attrs, name: str, kind: type, where: str, default: str | None = None):
    """A JSON attribute, of the type it must have."""
    text = attrs.get(name, default)
    if text is None:
        raise BankError(f"{where}: no {name}; {DAMAGED}")
    try:
        value = json.loads(as_str(text))
    except ValueError as e:
        raise BankError(f"{where}: {name} is not JSON ({e}); {DAMAGED}") from None
    if not isinstance(value, kind):
        want = "an object" if kind is dict else "a list"
        raise BankError(f"{where}: {name} is {type(value).__name__} JSON, expected {want}; {DAMAGED}")
    return value


def write_bank(path, bank: Bank, rooms=None, provenance: dict | None = None, progress=None,
               overwrite: bool = False, check: bool = True) -> Path:
    """Write ``bank`` (any kind) to ``path`` in the native format, one trajectory at a time.

    rooms: names or numbers to keep (default all). provenance: JSON-able facts stored
    in the file (source, command, seed...). overwrite: replace an existing file (refused
    otherwise). check: refuse, before writing, a room whose positions or RIR shapes cannot
    be trusted (banks/plausible.py; tests turn it off to write damaged banks). The file
    is written under a temporary name and renamed when whole; a disk that cannot hold it
    is refused before the first byte, and a failed write is one WriteError line naming the
    file. Returns the path.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise BankError(f"{path} already exists; choose another --out, or pass --force to replace it")
    names = [bank.resolve_room(r) for r in rooms] if rooms else list(bank.rooms)
    for room in names if check else ():
        problem = positions_problem(bank, room) or rirs_problem(bank, room, content=False)
        if problem:
            raise problem
    rooms_out = _shapes(bank, names)
    tmp = path.with_name(path.name + ".tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        _check_space(path, rooms_out)
        _write(tmp, bank, rooms_out, provenance, progress)
        os.replace(tmp, path)
    except (OSError, RuntimeError) as e:  # h5py reports some write failures as RuntimeError
        raise write_error(shown_path(str(path)), e, str(path.parent.absolute())) from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def _shapes(bank: Bank, names: list) -> list[tuple[str, list, int, int]]:
    """(room, trajectories, channels, RIR length) of every room the file will hold (a
    room with no RIRs is left out). The longest RIR sets the room's length (shorter ones
    are zero-padded)."""
    out = []
    for room in names:
        trajs = bank.trajectories(room)
        if sum(len(t) for t in trajs) == 0:
            continue
        heads = [bank.read(room, t.id, [0]).shape[1:] for t in trajs]
        out.append((room, trajs, heads[0][0], max(s[1] for s in heads)))
    return out


def _check_space(path: Path, rooms: list) -> None:
    """Refuse, before the first byte, a bank the disk cannot hold: HDF5 that runs out of
    space mid-file fails again on closing, and can take the process down with it."""
    need = sum(sum(len(t) for t in trajs) * (C * L * 4 + 3 * 8) for _, trajs, C, L in rooms)
    need = int(need * 1.02) + (1 << 20)  # chunk index, attributes, trajectories
    free = shutil.disk_usage(path.parent).free
    if free < need:
        raise WriteError(f"cannot write {shown_path(str(path))}: the bank takes about {need / 1e6:.1f} MB and the "
                         f"disk has {free / 1e6:.1f} MB free; free space or write to another disk")


def _write(tmp: Path, bank: Bank, rooms: list, provenance: dict | None, progress) -> None:
    prov = {"source": str(bank.source), "source_kind": bank.kind, **(provenance or {})}
    with h5py.File(tmp, "w", track_order=True) as f:
        f.attrs["tsel_bank"] = VERSION
        f.attrs["fs"] = int(bank.fs)
        f.attrs["format"] = bank.format
        f.attrs["channel_names"] = json.dumps(list(bank.channel_names))
        f.attrs["provenance"] = json.dumps(prov, sort_keys=True)
        top = f.create_group("rooms", track_order=True)
        for room, trajs, C, L in rooms:
            n = sum(len(t) for t in trajs)
            g = top.create_group(room)
            g.attrs["info"] = json.dumps(bank.room_info(room), sort_keys=True)
            rirs = g.create_dataset("rirs", (n, C, L), dtype="f4", chunks=(1, C, L), track_times=False)
            pos = np.zeros((n, 3))
            off = [0]
            for t in trajs:
                a = off[-1]
                data = bank.read(room, t.id, np.arange(len(t)))
                if data.shape[1:] != (C, L):
                    data = _fit(data, C, L, f"{room}/{t.id}")
                rirs[a : a + len(t)] = data
                pos[a : a + len(t)] = t.positions
                off.append(a + len(t))
                if progress:
                    progress(room, t)
            g.create_dataset("positions", data=pos, track_times=False)
            g.create_dataset("traj_offsets", data=np.asarray(off, dtype=np.int64), track_times=False)
            g.create_dataset("traj_ids", data=np.array([str(t.id) for t in trajs], dtype=h5py.string_dtype()), track_times=False)
            g.create_dataset("traj_kinds", data=np.array([t.kind for t in trajs], dtype=h5py.string_dtype()), track_times=False)
            g.create_dataset("traj_closed", data=np.array([t.closed for t in trajs], dtype=bool), track_times=False)


def _fit(data: np.ndarray, C: int, L: int, where: str) -> np.ndarray:
    """Zero-pad RIRs to the room's length L (trajectories may differ slightly)."""
    if data.shape[1] != C:
        raise BankError(f"{where}: {data.shape[1]} channels, expected {C}")
    out = np.zeros((len(data), C, L), dtype=np.float32)
    n = min(L, data.shape[2])
    out[:, :, :n] = data[:, :, :n]
    return out
