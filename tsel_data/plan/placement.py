"""Where a scene's sources and array go: in a simulated room (static, along a line, an arc
or a circle) or on a bank room's measured positions and trajectories.

:func:`place` and :func:`place_bank` are the planner's geometry (:mod:`tsel_data.plan.sampler`
draws everything else). Each draws from the scene's generator only, so a scene's
placement depends on (seed, split, index) alone. A source's distance, height, motion,
path kind and speed are drawn once (:class:`_Want`) and kept while the geometry is retried.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..banks.paths import sample_bank_path, sample_bank_point
from ..banks.scenes import open_bank_cached, split_rooms
from ..choices import Motion, PathKind, Spatial
from ..config import Config
from ..config.receiver import array_pose, receiver_names
from ..core.geometry import Room, frame_centres, interpolate_positions, wrap_azimuth
from ..errors import GeometryError
from ..receivers import ArrayPose, receiver
from ..scene.recipe import BankRef, BankWalk

MAX_TRIES = 200

@dataclass(frozen=True)
class _Want:
    """What a directional source must be, drawn once per scene and kept through every
    retry of the geometry: redrawing one of these alone when a layout does not fit would
    bias its distribution toward what fits (short distances, slow speeds)."""

    distance: float  # m from the array centre
    height: float  # m above the floor
    moving: bool
    kind: str = ""  # PathKind, for a moving source
    speed: float = 0.0  # °/s great-circle, for a moving source

    def describe(self, duration: float) -> str:
        motion = f"{'an' if self.kind == PathKind.ARC else 'a'} {self.kind} path at {self.speed:g}°/s (scene.speed), " if self.moving else ""
        text = f"{motion}{self.distance:.2f} m from the array (sources.distance), {self.height:.2f} m high"
        if self.moving and self.kind == PathKind.LINE:  # v = speed·distance, straight on
            text += f", {math.radians(self.speed) * self.distance * duration:.1f} m long in {duration:g} s"
        return text


def _wants(cfg: Config, rng, spatial: list[str]) -> list[_Want | None]:
    out = []
    for sp in spatial:
        if sp != Spatial.DIRECTIONAL:
            out.append(None)
            continue
        d, h = float(cfg.sources.distance.sample(rng)), float(cfg.sources.height.sample(rng))
        mv = _moves(cfg, rng)
        kind = str(cfg.scene.path.sample(rng)) if mv else ""
        speed = float(cfg.scene.speed.sample(rng)) if mv else 0.0
        out.append(_Want(d, h, mv, kind, speed))
    return out


ROOM_TRIES, CENTRE_TRIES, AZIMUTH_TRIES = 10, 10, 50


def place(cfg: Config, rng, spatial: list[str], split: str, index: int):
    """Room, the receivers' poses (``scene.format`` first, then ``scene.receivers``, all at
    one place) and each source's placement (Source fields; None for additive).

    Each directional source's distance, height, motion, path kind and speed are drawn
    first and kept; what is retried until the sources fit (inside the walls' margins,
    ``scene.min_separation`` apart) is the rest of the geometry: the source's azimuth and
    path (direction, time of closest approach), the array's place, and the room. So the
    configured distributions are what the dataset holds, and a setting the rooms cannot
    hold is an error that names it.
    """
    rc, ac = cfg.room, cfg.array
    sized = receiver(cfg.scene.format).size_key == "side"
    names = receiver_names(cfg)
    wants = _wants(cfg, rng, spatial)
    for _ in range(ROOM_TRIES):
        dims = (float(rc.length.sample(rng)), float(rc.width.sample(rng)), float(rc.height.sample(rng)))
        room = Room(tuple(round(d, 4) for d in dims), round(float(rc.rt60.sample(rng)), 4))
        side = round(float(ac.side.sample(rng)), 5) if sized else None
        yaw = round(float(ac.yaw.sample(rng)), 4)
        for _ in range(CENTRE_TRIES):
            centre = (
                float(rng.uniform(ac.wall_margin, room.dims[0] - ac.wall_margin)),
                float(rng.uniform(ac.wall_margin, room.dims[1] - ac.wall_margin)),
                float(min(ac.height.sample(rng), room.dims[2] - 0.1)),
            )
            centre = tuple(round(c, 5) for c in centre)
            places = _place_sources(cfg, rng, wants, room, centre, yaw)
            if places is not None:
                if len(names) > 1 and side is None and any(receiver(n).size_key == "side" for n in names[1:]):
                    side = round(float(ac.side.sample(rng)), 5)  # drawn last: the rest is as without them
                return room, [array_pose(cfg, centre, yaw, side, fmt=n) for n in names], places
    shown = "; ".join(f"source {k}: {w.describe(cfg.audio.duration)}" for k, w in enumerate(wants) if w is not None)
    if sum(w is not None for w in wants) > 1:
        apart = f", {cfg.scene.min_separation}° apart (scene.min_separation),"
        lower = f"scene.min_separation{_separation_hint(spatial)} or the settings named"
    else:
        apart, lower = "", "the settings named"
    raise GeometryError(
        f"scene {split}/{index}: could not place its sources ({shown}){apart} in {ROOM_TRIES} rooms drawn from "
        f"room.length/width/height; lower {lower}, lower the wall margins, or enlarge the rooms"
    )


def _separation_hint(spatial: list[str]) -> str:
    """What scene.min_separation can be for these sources: k directional sources fit at
    most 360°/k apart, and placement draws azimuths at random, so it needs a margin."""
    k = sum(sp == Spatial.DIRECTIONAL for sp in spatial)
    return f" (at most {360 / k:g}° is possible for {k} directional sources, random placement needs less)" if k > 1 \
        else ""


def _moves(cfg: Config, rng) -> bool:
    m = cfg.scene.motion
    return m == Motion.MOVING or (m == Motion.MIXED and bool(rng.random() < cfg.scene.moving_fraction))


def _frame_centres(cfg: Config) -> np.ndarray:
    a = cfg.audio
    return frame_centres(int(round(a.duration / a.label_hop)), a.label_hop)


def _separated(az: np.ndarray, placed: list[np.ndarray], sc) -> bool:
    """Whether azimuth track ``az`` [F] keeps ``sc.min_separation`` from every placed track
    on at least ``sc.separated_frames`` of the label frames.

    Static sources are separated on every frame or none; a moving source may cross
    another one (at 40°/s a 10 s walk goes all the way round) for the rest.
    """
    for p in placed:
        d = np.abs(wrap_azimuth(az - p))
        if np.mean(d >= sc.min_separation) < sc.separated_frames - 1e-9:
            return False
    return True


def _place_sources(cfg, rng, wants: list, room: Room, centre, yaw):
    """Every source's place for this room and array position, or None when one does not
    fit (the caller then draws another position or room)."""
    m = cfg.sources.wall_margin
    dims = room.dims
    fc = _frame_centres(cfg)
    placed: list[np.ndarray] = []  # azimuth track of each directional source at the label frames
    out = []
    for w in wants:
        if w is None:
            out.append(None)
            continue
        dz = w.height - centre[2]
        if abs(dz) >= w.distance or not m <= w.height <= dims[2] - m:
            return None  # no azimuth helps: this array height (or room) cannot hold it
        r_h = math.sqrt(w.distance ** 2 - dz * dz)
        for _ in range(AZIMUTH_TRIES):
            az = float(rng.uniform(-180.0, 180.0))
            if w.moving:
                place = _moving_path(cfg, rng, room, centre, yaw, az, r_h, w, fc)
                if place is None:
                    continue
                track = place.pop("_track")
            else:
                # array frame -> room frame by hand: numpy per point is slower than the maths
                a = math.radians(az + yaw)
                p = (centre[0] + r_h * math.cos(a), centre[1] + r_h * math.sin(a), w.height)
                if not all(m <= p[k] <= dims[k] - m for k in range(3)):
                    continue
                place = {"position": tuple(round(v, 6) for v in p)}
                track = np.full(len(fc), az)
            if _separated(track, placed, cfg.scene):
                placed.append(track)
                out.append(place)
                break
        else:
            return None
    return out


# A moving source's RIRs are computed at least every 100 ms, every 4 degrees and every
# KNOT_TRAVEL_M[kind] of its path (docs/acoustics.md, "Moving sources"). Arcs closer:
# 6 cm left 19.8-21.4 dB against the dense reference for 40 °/s arcs in the demo's two
# smallest rooms, 4.5 cm 23.1-24.6 dB (benchmarks/bench_moving_reflections.py accuracy).
KNOT_HOP_S, KNOT_STEP_DEG = 0.1, 4.0
KNOT_TRAVEL_M = {"line": 0.06, "arc": 0.045}


def knot_hop(kind: str, speed: float, distance: float, r_h: float) -> float | None:
    """Seconds between a simulated path's knots (None: the source does not move).

    ``speed`` °/s seen from the array at ``distance`` m, ``r_h`` m the horizontal
    distance: at most KNOT_HOP_S, KNOT_STEP_DEG of azimuth and KNOT_TRAVEL_M[kind] of travel.
    Between knots every image source moves with the delay of its group
    (acoustics/image_paths.py), the direct path exactly; what is left combs in
    proportion to the travel between knots, for arcs too (their side walls' reflections
    move as fast as the source).
    """
    if speed <= 0:
        return None
    hop = min(KNOT_HOP_S, KNOT_STEP_DEG / (speed * distance / r_h))
    return min(hop, KNOT_TRAVEL_M[kind] / (math.radians(speed) * distance))


def _moving_path(cfg, rng, room: Room, centre, yaw, az0: float, r_h: float, want: "_Want", fc: np.ndarray):
    """A simulated moving source at constant height, or None if it does not fit the room:
    ``{"path": ((t, x, y, z), ...) room frame, "_track": azimuth (array frame) at the label frames}``.

    ω = ``scene.speed`` is the angular speed seen from the array (great-circle °/s, as
    for bank walks). ``arc``: around the array at horizontal distance r_h (distance d),
    so the azimuth turns at ω·d/r_h. ``line``: a straight pass, perpendicular to azimuth
    az0 at horizontal distance r_h when closest (at a time drawn over the clip), at the
    speed v = ω·d that sweeps ω °/s there, the fastest it gets; the azimuth then turns at
    most ω·d/r_h. A pass longer than the room's chord through that closest point walks
    the whole chord at that speed and stands at the wall margin before and after
    (docs/acoustics.md, "Moving sources"). Knots every :func:`knot_hop`: at least every 100 ms, every 4° of
    azimuth and every 6 cm of travel.
    """
    kind, speed, d, h = want.kind, want.speed, want.distance, want.height
    direction = 1 if rng.random() < 0.5 else -1
    dur, m = cfg.audio.duration, cfg.sources.wall_margin
    az_rate = speed * d / r_h  # °/s of azimuth: the arc's, and the line's at its closest
    hop = knot_hop(kind, speed, d, r_h) or dur
    t = np.arange(0.0, dur + hop - 1e-9, hop)
    if not m <= h <= room.dims[2] - m:
        return None
    if kind == PathKind.ARC:
        a = np.radians(az0 + yaw + direction * az_rate * t)
        x, y = centre[0] + r_h * np.cos(a), centre[1] + r_h * np.sin(a)
        track = az0 + direction * az_rate * fc
        if x.min() < m or y.min() < m or x.max() > room.dims[0] - m or y.max() > room.dims[1] - m:
            return None
    else:
        a0 = math.radians(az0 + yaw)
        p0 = np.array([centre[0] + r_h * math.cos(a0), centre[1] + r_h * math.sin(a0)])
        u = direction * np.array([-math.sin(a0), math.cos(a0)])  # the way it walks
        chord = _chord(p0, u, room.dims, m)
        if chord is None:
            return None
        v = math.radians(speed) * d
        t_close = float(rng.uniform(*_closest_times(chord, v, dur)))
        # beyond the chord the source stands at the wall margin: a pass longer than the
        # room keeps its speed and its closest approach, and walks wall to wall
        s = np.clip(v * (t - t_close), *chord)  # metres along u from the closest point
        x, y = p0[0] + s * u[0], p0[1] + s * u[1]
        track = az0 + direction * np.degrees(np.arctan2(np.clip(v * (fc - t_close), *chord), r_h))
    path = tuple((round(float(ti), 6), round(float(xi), 6), round(float(yi), 6), round(h, 6))
                 for ti, xi, yi in zip(t, x, y))
    return {"path": path, "_track": track}


def _chord(p0: np.ndarray, u: np.ndarray, dims, m: float) -> tuple[float, float] | None:
    """The part [s_min, s_max] (m along unit ``u`` from ``p0``) of a horizontal line that
    lies inside the room's wall margins, or None when ``p0`` itself is outside them."""
    lo, hi = -math.inf, math.inf
    for k in range(2):
        a, b = m - p0[k], dims[k] - m - p0[k]
        if a > 0 or b < 0:
            return None
        if abs(u[k]) > 1e-12:
            ends = sorted((a / u[k], b / u[k]))
            lo, hi = max(lo, ends[0]), min(hi, ends[1])
    return lo, hi


def _closest_times(chord: tuple[float, float], v: float, dur: float) -> tuple[float, float]:
    """The times of closest approach (within the clip) at which a pass at ``v`` m/s stays
    on ``chord`` for the whole clip or, when the pass is longer than the chord, walks all
    of it. A pass that fits anywhere draws over the whole clip, as before passes fitted."""
    s_min, s_max = chord
    late, early = dur - s_max / v, -s_min / v  # leaves the chord at the end / started before it
    return max(0.0, min(late, early)), min(dur, max(late, early))


# --- RIR-bank scenes ----------------------------------------------------------------------


def place_bank(cfg: Config, rng, spatial: list[str], split: str, index: int, bank_path: str):
    """A bank room for the split, the bank's array, and each source's walk or point:
    (None, [ArrayPose per receiver], [{"bank": BankWalk} or None per source], BankRef)."""
    spec = receiver(cfg.scene.format)
    bank = open_bank_cached(bank_path, spec.bank_format)
    rooms = split_rooms(bank, cfg.rooms_by_split(), split)
    room_name = rooms[int(rng.integers(len(rooms)))]
    info = bank.room_info(room_name)
    side = (info.get("array") or {}).get("side") if spec.size_key == "side" else None
    # the bank's RIRs hold the real capsules (baffle and all); a mixed receiver mixes them (render)
    array = [ArrayPose(receiver(n).name, (0.0, 0.0, 0.0), 0.0, side if receiver(n).size_key == "side" else None)
             for n in receiver_names(cfg)]
    fc = _frame_centres(cfg)
    placed: list[np.ndarray] = []
    out = []
    for sp in spatial:
        if sp != Spatial.DIRECTIONAL:
            out.append(None)
            continue
        mv = _moves(cfg, rng)
        speed = float(cfg.scene.speed.sample(rng)) if mv else 0.0  # kept through the retries (see _Want)
        for _ in range(MAX_TRIES // 4):
            if mv:
                tid, idx, times = sample_bank_path(bank, room_name, rng, cfg.audio.duration, speed,
                                                   knot_hop=KNOT_HOP_S)
            else:
                tid, i0 = sample_bank_point(bank, room_name, rng)
                idx, times = np.array([i0]), np.array([0.0])
            pos = bank.trajectory(room_name, tid).positions[idx]
            track = interpolate_positions(times, pos, fc)[:, 0]
            if _separated(track, placed, cfg.scene):
                placed.append(track)
                out.append({"bank": BankWalk(
                    room_name, tid, tuple(int(v) for v in idx), tuple(round(float(v), 6) for v in times),
                    tuple(tuple(round(float(v), 4) for v in p) for p in pos))})
                break
        else:
            raise GeometryError(f"scene {split}/{index}: could not place sources {cfg.scene.min_separation}° apart "
                                f"in bank room {room_name}; lower scene.min_separation{_separation_hint(spatial)}")
    return None, array, out, BankRef(bank_path, room_name)
