"""How a dataset uses an RIR bank: which bank file, which rooms each split may draw,
what must hold before planning, and one open bank per process for planning and
rendering.

Everything here takes plain values (:class:`BankRequest`), not the config, so the
bank layer stays below the config and the sampler (docs/design.md).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

from ..errors import BankError, ConfigError, TselError
from ..receivers import receiver
from ..scene.recipe import BUILTIN_DEMO_BANK
from .build import DEMO, build_bank
from .kinds import open_bank
from .plausible import positions_problem, rirs_problem



@dataclass(frozen=True)
class BankRequest:
    """What a dataset asks of a bank.

    path: ``room.bank`` as configured (a path, ``builtin:demo-bank``, or empty for none).
    format: the scenes' array format. fs: the scenes' sample rate (Hz). rooms:
    ``splits.NAME.rooms`` of every split (names or numbers; empty: unlisted). active:
    the splits that make scenes now.
    """

    path: str
    format: str
    fs: int
    rooms: dict = field(default_factory=dict)
    active: tuple = ()


def resolve_bank(req: BankRequest, demo_path: str) -> str | None:
    """The bank file scenes will use (absolute), checked against the request; None without one.

    ``builtin:demo-bank`` builds the demo bank (:data:`~tsel_data.banks.build.DEMO`) into
    ``demo_path`` once. Raises the first of :func:`bank_problems`.
    """
    path = req.path
    if not path:
        return None
    if path == BUILTIN_DEMO_BANK:
        path = demo_path
        if not os.path.exists(path):
            build_bank(path, format=req.format, seed=0, fs=req.fs, **DEMO)
    path = os.path.abspath(os.path.expanduser(path))
    problems = bank_problems(BankRequest(path, req.format, req.fs, req.rooms, req.active))
    if problems:
        raise problems[0]
    return path


_BANKS: dict = {}


def open_bank_cached(path: str, fmt: str | None = None):
    """One open bank per process, path and array format (banks read lazily, so this stays
    small). ``fmt`` picks the format where a bank holds several (TAU's foa and mic, a
    folder of SpatialScaper's _foa and _mic SOFA files)."""
    key = (path, fmt)
    if key not in _BANKS:
        _BANKS[key] = open_bank(path, format=fmt)
    return _BANKS[key]


def split_rooms(bank, rooms: dict, split: str) -> list[str]:
    """The bank rooms ``split`` may use: its own ``rooms`` (names or numbers); if empty,
    the rooms no other split names (all of them when no split names any), so an
    unlisted split never draws another split's rooms."""
    wanted = rooms.get(split) or ()
    if wanted:
        return [bank.resolve_room(r) for r in wanted]
    claimed = set()
    for name, named in rooms.items():
        for r in named if name != split else ():
            try:
                claimed.add(bank.resolve_room(r))
            except TselError:
                pass  # not in this bank, so never drawn from it (bank_problems reports it for active splits)
    free = [r for r in bank.rooms if r not in claimed]
    if not free:
        raise ConfigError(f"splits.{split}.rooms is empty and every room of {bank.source} is named by another split; "
                          f"give splits.{split}.rooms its own rooms")
    return free


def bank_problems(req: BankRequest) -> list[TselError]:
    """Problems with the requested bank, all of them: missing or unreadable bank, array
    format or sample rate differing from the scenes', active splits' rooms the bank lacks
    or that two splits share, no room left for an unlisted split, rooms whose positions
    or RIRs cannot be trusted (banks/plausible.py), mic4 rooms without the array's side
    length. ``builtin:demo-bank`` has none (it is built to match)."""
    if not req.path or req.path == BUILTIN_DEMO_BANK:
        return []
    fmt = req.format
    try:
        path = os.path.abspath(os.path.expanduser(req.path))
        # a folder (TAU-SRIR DB, SpatialScaper's SOFA files) may hold several formats: take the scenes'
        bank = open_bank(path, format=fmt if os.path.isdir(path) else None)
    except TselError as e:
        return [e]
    except OSError as e:
        return [BankError(f"RIR bank {req.path}: cannot read it ({e.strerror or e}); check the path")]
    out: list[TselError] = []
    with bank:
        if bank.format != fmt:
            out.append(BankError(f"{bank.source}: the bank holds {bank.format} RIRs but scene.format = {fmt!r}; "
                                 f"set scene.format = \"{bank.format}\" or use a {fmt} bank"))
        try:
            bank.require_fs(req.fs)
        except TselError as e:
            out.append(e)
        if not bank.rooms:
            out.append(BankError(f"{bank.source}: the bank holds no rooms; rebuild or re-import it"))
            return out
        used: dict[str, str] = {}
        for split in req.active:
            # an inactive split may name rooms this bank lacks (made from another bank, or later)
            for key in req.rooms.get(split) or ():
                try:
                    room = bank.resolve_room(key)
                except TselError as e:
                    out.append(BankError(f"splits.{split}.rooms: {e}"))
                    continue
                if room in used and used[room] != split:
                    out.append(BankError(
                        f"splits.{split}.rooms: room {room} is also used by split {used[room]}; a room in two splits "
                        f"leaks its acoustics into evaluation; give each split its own rooms"))
                used.setdefault(room, split)
        unlisted = [s for s in req.active if not req.rooms.get(s)]
        if unlisted:
            try:  # the rooms no split names, shared by every split without rooms
                for room in split_rooms(bank, req.rooms, unlisted[0]):
                    used.setdefault(room, unlisted[0])
            except ConfigError as e:
                out.append(e)
        for room in used:
            e = positions_problem(bank, room) or _side_problem(bank, room) or rirs_problem(bank, room)
            if e:
                out.append(e)
    return out


def _side_problem(bank, room: str) -> TselError | None:
    """A sized array's mic positions (labels' mic_positions) need its side length."""
    if receiver(bank.format).size_key != "side":
        return None
    array = bank.room_info(room).get("array")
    side = array.get("side") if isinstance(array, dict) else None
    if isinstance(side, (int, float)) and side > 0:
        return None
    return BankError(f"{bank.source}: room {room} is a {bank.format} room without the array's side length "
                     f"(room info array.side); rebuild it with `tsel bank build` or add the side to its info")
