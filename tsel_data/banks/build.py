"""Build an RIR bank from the shoebox simulator, in the TAU-SRIR DB's shape.

Per room: a random shoebox (``dims`` ranges, RT60 range) with the array near its centre
at a random yaw; sources on horizontal circles around the array, one per (distance,
height offset) pair, a source every ``step_deg`` degrees of azimuth. Each circle is a
closed circular trajectory (so moving sources can go round), like TAU's measured
circles. All RIRs of a room come from one ``simulate_rirs`` call, so they share the
room's acoustics (and the hybrid method's late-tail seed).

Positions are exact: azimuth φ, elevation atan2(dz, r), distance hypot(r, dz) in the
array frame. The RIR length is the simulator's (the latest direct path plus RT60, so
tails are complete) unless ``rir_seconds`` cuts it.
"""
from __future__ import annotations

import os

import numpy as np

from ..acoustics import simulate_rirs
from ..core.geometry import Room, array_to_room, sph_to_cart
from ..errors import BankError, GeometryError
from ..receivers import ArrayPose, receiver
from .base import MemoryBank, Trajectory, check_format
from .native import write_bank

# The demo bank: 4 small rooms of circular trajectories at two distances and two heights,
# enough for rooms split by split (the demo-moving preset's builtin:demo-bank, and
# `tsel bank build --demo`). About 2 s to build at 24 kHz.
DEMO = dict(n_rooms=4, distances=(1.0, 2.0), heights=(-0.3, 0.3), step_deg=10.0)


def simulate_bank(format: str = "mic4", n_rooms: int = 2, seed: int = 0, fs: int = 24000,
                  distances=(1.0, 1.5), heights=(-0.3, 0.0, 0.3), step_deg: float = 5.0,
                  rt60=(0.3, 0.8), dims_min=(5.0, 4.5, 2.7), dims_max=(9.0, 7.0, 3.5),
                  side: float = 0.11, method: str | None = None, rir_seconds: float | None = None,
                  progress=None) -> MemoryBank:
    """A simulated bank in memory (see the module docstring); write it with ``write_bank``.

    format: array format. n_rooms: rooms to simulate. seed: room draws (room i uses
    ``(seed, i)``). fs: Hz. distances: ring radii around the array (m). heights: ring
    heights relative to the array (m). step_deg: azimuth step along each ring. rt60:
    (lo, hi) seconds, drawn per room. dims_min, dims_max: room size ranges (m). side:
    mic4 square side (m). method: RIR simulator (default hybrid). rir_seconds: cut RIRs
    to this length (default: full decay). progress: called with each room's name.
    """
    fmt = check_format(format)
    method = method or "hybrid"  # the toolkit's own simulator (acoustics/shoebox.py)
    spec = receiver(fmt)
    sized = spec.size_key == "side"
    if method == "pyroomacoustics" and not ArrayPose(fmt, (0.0, 0.0, 0.0), 0.0, side if sized else None).free_field_omnis:
        raise BankError(f"the pyroomacoustics method renders free-field omni capsules only; build {fmt} banks with "
                        f"method 'hybrid' or 'ism'")
    if not spec.bankable:
        raise BankError(f"bank build: {fmt} banks are not built (a bank holds one fixed array); simulate {fmt} scenes "
                        f"directly, without room.bank")
    distances = tuple(float(d) for d in distances)
    heights = tuple(float(h) for h in heights)
    numbers = {"distances": distances, "heights": heights, "RT60": tuple(rt60), "step": (step_deg,), "side": (side,)}
    for name, vals in numbers.items():
        if not all(np.isfinite(float(v)) for v in vals if v is not None):
            raise BankError(f"bank build: {name} {vals} must be finite numbers")
    if sized and not (side or 0) > 0:
        raise BankError(f"bank build: the {fmt} array's side {side} m must be positive")
    if rir_seconds is not None and not (np.isfinite(rir_seconds) and round(rir_seconds * fs) >= 1):
        raise BankError(f"bank build: RIR length {rir_seconds} s must be at least one sample at {fs} Hz")
    if not distances or min(distances) <= 0 or n_rooms < 1:
        raise BankError("bank build needs positive distances and at least one room")
    if not 0 < step_deg <= 90:
        raise BankError(f"bank build: step {step_deg} deg must be in (0, 90], so a circle holds at least 4 positions")
    if len(rt60) != 2 or not 0 < rt60[0] <= rt60[1]:
        raise BankError(f"bank build: RT60 range {tuple(rt60)} must be 'lo,hi' seconds with 0 < lo <= hi")
    if int(fs) < 8000:
        raise BankError(f"bank build: sample rate {fs} Hz is below 8000 Hz")
    az = np.arange(-180.0, 180.0 - 1e-9, float(step_deg))
    rooms, info = {}, {}
    for i in range(n_rooms):
        rng = np.random.default_rng([int(seed), i])
        dims = rng.uniform(dims_min, dims_max)
        reach = max(distances) + 0.3  # ring radius plus a margin to the walls
        slack = dims[:2] / 2 - reach
        if np.any(slack < 0):
            raise GeometryError(f"room {np.round(dims, 2).tolist()} cannot hold a {max(distances)} m ring; use smaller distances or larger rooms")
        z_lo, z_hi = 0.3 - min(heights + (0.0,)), dims[2] - 0.3 - max(heights + (0.0,))
        if z_hi < z_lo:
            raise GeometryError(f"room height {dims[2]:.2f} m cannot hold height offsets {heights}")
        centre = np.r_[dims[:2] / 2 + rng.uniform(-1, 1, 2) * np.minimum(slack, 0.5), rng.uniform(z_lo, min(z_hi, max(z_lo, 1.5)))]
        yaw = float(rng.uniform(-180.0, 180.0))
        room = Room(tuple(np.round(dims, 3).tolist()), float(np.round(rng.uniform(*rt60), 3)))
        array = ArrayPose(fmt, tuple(np.round(centre, 3).tolist()), round(yaw, 2), side if sized else None)
        rings, pts = [], []
        for di, r in enumerate(distances):
            for hi, dz in enumerate(heights):
                p_arr = sph_to_cart(az, 0.0, r) + np.array([0.0, 0.0, dz])
                rings.append((f"r{di}h{hi}", r, dz))
                pts.append(p_arr)
        # one call per ring: a ring is one source's path, so its knots share one late-tail
        # realisation (independent tails would dip 3 dB between crossfaded knots)
        seeds = rng.integers(2**31, size=len(pts))
        ring_rirs = [simulate_rirs(room, array, array_to_room(p, array.centre, array.yaw), fs, method=method,
                                   seed=int(sd), one_source=True).rirs for p, sd in zip(pts, seeds)]
        length = max(r.shape[-1] for r in ring_rirs)
        rirs = np.concatenate([np.pad(r, ((0, 0), (0, 0), (0, length - r.shape[-1]))) for r in ring_rirs])
        if rir_seconds:
            rirs = rirs[:, :, : int(round(rir_seconds * fs))]
        name = f"sim{i + 1:02d}"
        items = []
        for j, (tid, r, dz) in enumerate(rings):
            pos = np.stack([az, np.full_like(az, np.degrees(np.arctan2(dz, r))), np.full_like(az, np.hypot(r, dz))], axis=-1)
            items.append((Trajectory(name, tid, "circular", pos, True), rirs[j * len(az) : (j + 1) * len(az)]))
        rooms[name] = items
        info[name] = {
            "number": i + 1,
            "dims": list(room.dims),
            "rt60": room.rt60,
            "array": {"format": fmt, "centre": list(array.centre), "yaw": array.yaw, "side": array.side},
            "method": method,
        }
        if progress:
            progress(name)
    return MemoryBank(fs, fmt, rooms, info, source=f"simulated ({method})")


def build_bank(out, format: str = "mic4", n_rooms: int = 2, seed: int = 0, overwrite: bool = False, **kwargs):
    """Simulate a bank (:func:`simulate_bank`'s options) and write it to ``out`` (native
    format; an existing file only with ``overwrite``). Returns the path."""
    if os.path.exists(out) and not overwrite:  # before hours of simulation, not after
        raise BankError(f"{out} already exists; choose another --out, or pass --force to replace it")
    bank = simulate_bank(format=format, n_rooms=n_rooms, seed=seed, **kwargs)
    prov = {"builder": "tsel bank build", "seed": int(seed), "n_rooms": int(n_rooms),
            **{k: (list(v) if isinstance(v, tuple) else v) for k, v in kwargs.items() if k != "progress"}}
    return write_bank(out, bank, provenance=prov, overwrite=overwrite)
