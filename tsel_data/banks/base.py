"""The bank interface every kind of RIR bank implements, and the in-memory bank.

A *bank* holds, per room, RIRs measured or simulated from many source positions to one
array, each with its source position in the **array frame** (azimuth °, elevation °,
distance m; docs/format.md), grouped into *trajectories*: runs of positions ordered
along a path (a circle around the array, or a line), so a moving source is a walk
along one. Reading is lazy: :meth:`Bank.read` touches only the RIRs asked for.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import BankError
from ..receivers import NAMES, canonical, receiver

KINDS = ("circular", "linear")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One ordered run of bank positions.

    room: room name. id: trajectory id within the room (str or int). kind: ``circular``
    or ``linear``. positions: float64 [N, 3], (azimuth deg, elevation deg, distance m)
    in the array frame, ordered along the path. closed: True when the path is a full
    loop (the last position is followed by the first), so a walk may wrap around.
    """

    room: str
    id: str | int
    kind: str
    positions: np.ndarray
    closed: bool = False

    def __len__(self) -> int:
        return len(self.positions)


class Bank:
    """Common interface of every RIR bank.

    Attributes: ``fs`` (Hz), ``format`` (``foa`` | ``mic4`` | ``tetra``),
    ``channel_names`` (tuple of C names), ``rooms`` (list of room names), ``kind``
    (``tau`` | ``sofa`` | ``native`` | ``memory``), ``source`` (where it was read from).
    Subclasses implement :meth:`trajectories` and :meth:`_read`.
    """

    fs: int
    format: str
    channel_names: tuple
    rooms: list
    kind: str = "bank"
    source: str = ""

    # --- to implement ----------------------------------------------------------------
    def trajectories(self, room: str) -> list[Trajectory]:
        raise NotImplementedError

    def _read(self, room: str, traj: Trajectory, rows: np.ndarray) -> np.ndarray:
        """RIRs of sorted, unique positions ``rows`` of ``traj``: float32 [len(rows), C, L]."""
        raise NotImplementedError

    # --- shared ------------------------------------------------------------------------
    def room_info(self, room: str) -> dict:
        """Extra facts about a room (``number`` for TAU rooms, dims, provenance)."""
        self.check_room(room)
        return {}

    def resolve_room(self, key) -> str:
        """Room name for a name or a room number (TAU numbers rooms 1–6, 8–10)."""
        if isinstance(key, str) and key in self.rooms:
            return key
        try:
            num = int(key)
        except (TypeError, ValueError):
            num = None
        if num is not None:
            for r in self.rooms:
                if self.room_info(r).get("number") == num:
                    return r
        raise BankError(f"{self.source}: no room {key!r}; rooms are {self._room_list()}")

    def require_fs(self, fs: int) -> None:
        """Raise BankError unless the bank's sample rate is ``fs`` (banks are never resampled silently)."""
        if int(fs) != int(self.fs):
            raise BankError(f"{self.source}: RIRs are at {self.fs} Hz but the scenes are at {int(fs)} Hz; set audio.fs = {self.fs} or use a bank at {int(fs)} Hz")

    def check_room(self, room: str) -> None:
        if room not in self.rooms:
            raise BankError(f"{self.source}: no room {room!r}; rooms are {self._room_list()}")

    def trajectory(self, room: str, traj_id) -> Trajectory:
        for t in self.trajectories(room):
            if t.id == traj_id or str(t.id) == str(traj_id):
                return t
        ids = [t.id for t in self.trajectories(room)]
        raise BankError(f"{self.source}: room {room!r} has no trajectory {traj_id!r}; it has {ids}")

    def _mapped(self, room: str, traj: Trajectory):
        """The RIRs of ``traj`` as a sequence of read-only float32 [C, L] arrays mapped
        from the bank file (item i is position i), where the bank can map it; else None."""
        return None

    def read(self, room: str, traj_id, indices) -> np.ndarray:
        """RIRs at positions ``indices`` of trajectory ``traj_id``: float32 [len(indices), C, L].

        Only those RIRs are read from disk; indices may repeat and come in any order.
        """
        traj, idx = self._indices(room, traj_id, indices)
        rows, inverse = np.unique(idx, return_inverse=True)
        out = self._read(room, traj, rows)
        return np.ascontiguousarray(out[inverse], dtype=np.float32)

    def views(self, room: str, traj_id, indices) -> list[np.ndarray]:
        """RIRs at positions ``indices`` as a list of read-only float32 [C, L] arrays.

        Banks whose file can be memory-mapped (our own format) give views into the file,
        so nothing is copied until the RIRs are used (``render_moving`` takes such a
        list); other banks read them (:meth:`read`).
        """
        traj, idx = self._indices(room, traj_id, indices)
        rows = self._mapped(room, traj)
        if rows is None:
            return list(self.read(room, traj_id, idx))
        return [rows[i] for i in idx]

    def _indices(self, room: str, traj_id, indices) -> tuple[Trajectory, np.ndarray]:
        traj = self.trajectory(room, traj_id)
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        if idx.size == 0:
            raise BankError(f"{self.source}: no RIR indices asked for in {room}/{traj_id}")
        if idx.min() < 0 or idx.max() >= len(traj):
            raise BankError(
                f"{self.source}: index {int(idx.max() if idx.max() >= len(traj) else idx.min())} out of range "
                f"for {room}/{traj_id}, which has {len(traj)} RIRs"
            )
        return traj, idx

    def summary(self, trajectories: bool = False) -> dict:
        """Plain-data description for ``tsel bank info``: rooms, RIR counts, coverage;
        ``trajectories=True`` adds each room's ``trajectory_list`` (id, kind, closed, RIRs,
        first and last azimuth, mean elevation and distance)."""
        rooms = []
        for r in self.rooms:
            trajs = self.trajectories(r)
            pos = np.concatenate([t.positions for t in trajs]) if trajs else np.zeros((0, 3))
            room = {
                "room": r,
                **{k: v for k, v in self.room_info(r).items() if k in ("number",)},
                "trajectories": len(trajs),
                "kinds": sorted({t.kind for t in trajs}),
                "rirs": int(len(pos)),
                "azimuth_coverage_deg": azimuth_coverage(pos[:, 0]) if len(pos) else 0.0,
                "elevation_range_deg": _range(pos[:, 1]),
                "distance_range_m": _range(pos[:, 2]),
            }
            if trajectories:
                room["trajectory_list"] = [
                    {"id": str(t.id), "kind": t.kind, "closed": t.closed, "rirs": len(t),
                     "azimuth": [round(float(t.positions[0, 0]), 1), round(float(t.positions[-1, 0]), 1)],
                     "elevation_mean": round(float(t.positions[:, 1].mean()), 1),
                     "distance_mean": round(float(t.positions[:, 2].mean()), 2)}
                    for t in trajs
                ]
            rooms.append(room)
        return {
            "source": str(self.source),
            "kind": self.kind,
            "fs": int(self.fs),
            "format": self.format,
            "channels": list(self.channel_names),
            "rooms": rooms,
            "rirs": int(sum(r["rirs"] for r in rooms)),
        }

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _room_list(self) -> str:
        return ", ".join(map(str, self.rooms)) or "(none)"


def azimuth_coverage(az, max_gap_deg: float = 20.0) -> float:
    """Degrees of the azimuth circle not inside a gap wider than ``max_gap_deg`` between positions."""
    az = np.asarray(az, dtype=np.float64)
    az = np.unique(np.round(az[np.isfinite(az)] % 360.0, 6))
    if az.size == 0:
        return 0.0
    gaps = np.diff(np.r_[az, az[0] + 360.0])
    return float(round(360.0 - gaps[gaps > max_gap_deg].sum(), 3))


def _range(v) -> list:
    v = np.asarray(v, dtype=np.float64)
    v = v[np.isfinite(v)]
    return [round(float(v.min()), 3), round(float(v.max()), 3)] if v.size else [None, None]


MIN_RATE, MAX_RATE = 1000, 1_000_000  # Hz: what an RIR can be sampled at


def check_rate(value, where: str) -> int:
    """A bank's sample rate as an integer number of Hz; BankError (naming ``where``) for
    anything else: NaN, 0, text, a fraction, a rate no RIR is sampled at."""
    v = np.asarray(value)
    fs = float(v.reshape(-1)[0]) if v.size == 1 and v.dtype.kind in "iuf" else float("nan")
    if not (np.isfinite(fs) and MIN_RATE <= fs <= MAX_RATE and abs(fs - round(fs)) < 1e-6):
        shown = v.reshape(-1).tolist()[0] if v.size == 1 else value
        raise BankError(f"{where}: the sample rate is {shown!r}, not a rate in Hz ({MIN_RATE}..{MAX_RATE}); the bank "
                        f"is damaged: re-import or rebuild it")
    return int(round(fs))


def check_format(fmt: str, where: str = "") -> str:
    """A receiver's own name for ``fmt`` (TAU's ``mic`` is our ``tetra``: receivers' aliases)."""
    f = canonical(fmt)
    if f is None:
        raise BankError(f"{where}unknown array format {fmt!r}; expected one of {', '.join(NAMES)} (or 'mic' for tetra)")
    return f


# --- an in-memory bank (simulated banks before they are written; tests) -------------------
@dataclass
class _MemRoom:
    trajectories: list
    rirs: dict  # traj id -> float32 [N, C, L]
    info: dict = field(default_factory=dict)


class MemoryBank(Bank):
    """A bank held in memory: ``rooms = {name: [(Trajectory, rirs [N, C, L]), ...]}``."""

    kind = "memory"

    def __init__(self, fs: int, format: str, rooms: dict, info: dict | None = None, source: str = "<memory>"):
        self.fs = int(fs)
        self.format = check_format(format)
        self.channel_names = receiver(self.format).channels(n=_channels(rooms))
        self.source = source
        self._rooms = {}
        for name, items in rooms.items():
            trajs = [t for t, _ in items]
            rirs = {t.id: np.asarray(r, dtype=np.float32) for t, r in items}
            for t, r in items:
                if len(r) != len(t):
                    raise BankError(f"{source}: {name}/{t.id} has {len(t)} positions but {len(r)} RIRs")
            self._rooms[name] = _MemRoom(trajs, rirs, dict((info or {}).get(name, {})))
        self.rooms = list(self._rooms)

    def trajectories(self, room):
        self.check_room(room)
        return list(self._rooms[room].trajectories)

    def room_info(self, room):
        self.check_room(room)
        return dict(self._rooms[room].info)

    def _read(self, room, traj, rows):
        return self._rooms[room].rirs[traj.id][rows]


def _channels(rooms: dict) -> int | None:
    """The channel count of a memory bank's RIRs (a custom array's names follow it)."""
    for items in rooms.values():
        for _, r in items:
            return int(np.asarray(r).shape[1])
    return None
