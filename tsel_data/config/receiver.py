"""The config's receiver as an :class:`~tsel_data.receivers.ArrayPose`: what the planner
puts in every recipe and what the rules, the job and the shards ask of it (channels,
radius), built in one place from ``scene.format`` and ``[array]``."""
from __future__ import annotations

import math
import os

from ..choices import ReceiverModel
from ..core.files import path_problem
from ..errors import ConfigError
from ..receivers import MAX_CHANNELS, NAMES, PATTERN_ALPHA, ArrayPose, canonical, receiver
from .schema import Config


def array_pose(cfg: Config, centre=(0.0, 0.0, 0.0), yaw: float = 0.0, side: float | None = None,
               hrtf: str | None = None, fmt: str | None = None) -> ArrayPose:
    """The receiver of ``cfg`` at ``centre`` (room frame, m) turned by ``yaw`` degrees.

    side: mic4's side (m), drawn per scene; hrtf: a binaural receiver's SOFA file as the
    plan names it (relative to its root); fmt: another receiver than ``scene.format`` (one
    of ``scene.receivers``). A custom array's capsules, patterns and
    orientations are resolved here (one pattern for all, axes pointing away from the
    centre by default) and stored whole, so its recipes need nothing else.
    """
    spec = receiver(fmt or cfg.scene.format)
    a = cfg.array
    kw = {}
    if spec.configured:
        kw = custom_capsules(a.capsules, a.patterns, a.orientations)
    if spec.model == ReceiverModel.SPHERE:
        kw["baffle"] = a.baffle
    if spec.model == ReceiverModel.HRTF:
        # the recipe names the file as the bank's is named; Roots.hrtf says where it is
        kw["hrtf"] = hrtf if hrtf is not None else os.path.basename(os.path.normpath(a.hrtf))
        kw["interpolation"] = a.hrtf_interpolation
    return ArrayPose(spec.name, tuple(centre), yaw, side if spec.size_key == "side" else None, **kw)


def receiver_names(cfg: Config) -> tuple[str, ...]:
    """Every receiver of ``cfg``: ``scene.format`` first, then ``scene.receivers``."""
    return (receiver(cfg.scene.format).name, *(receiver(r).name for r in cfg.scene.receivers))


def array_poses(cfg: Config, centre=(0.0, 0.0, 0.0), yaw: float = 0.0, side: float | None = None) -> list:
    """Every receiver of ``cfg`` at one place (:func:`array_pose` each; one side for all sized ones)."""
    return [array_pose(cfg, centre, yaw, side, fmt=name) for name in receiver_names(cfg)]


def custom_capsules(capsules, patterns=(), orientations=()) -> dict:
    """ArrayPose fields of a custom array: ``capsules`` as float tuples, and when any
    capsule is not omni, a pattern and an axis (azimuth °, elevation °) per capsule
    (``orientations`` empty: away from the array centre; a capsule at the centre faces +x)."""
    caps = tuple(tuple(float(v) for v in c) for c in capsules)
    n = len(caps)
    pats = tuple(patterns) * n if len(patterns) == 1 else tuple(patterns)
    if not pats or all(p == "omni" for p in pats):
        return {"capsules": caps}
    if orientations:
        ors = tuple(orientations) * n if len(orientations) == 1 else tuple(orientations)
        ors = tuple((float(o[0]), float(o[1])) for o in ors)
    else:
        ors = tuple(_outward(c) for c in caps)
    return {"capsules": caps, "patterns": pats, "orientations": ors}


def _outward(p) -> tuple[float, float]:
    x, y, z = p
    if math.hypot(x, y, z) < 1e-9:
        return (0.0, 0.0)
    return (round(math.degrees(math.atan2(y, x)), 6), round(math.degrees(math.atan2(z, math.hypot(x, y))), 6))



def receiver_problems(cfg: Config, where: str) -> list[ConfigError]:
    """What a receiver needs from ``[array]`` and nothing it cannot use: a custom array's
    capsule table (1-64 finite positions, no two omnis at one point, known patterns, one
    axis per capsule or one for all), a binaural receiver's HRTF file, and no custom or
    binaural key set for another receiver."""
    fmt = cfg.scene.format
    if canonical(fmt) is None:
        return []  # field_problems names it, with the choices
    a = cfg.array
    out: list[ConfigError] = []
    names = [fmt, *cfg.scene.receivers]
    unknown = [r for r in cfg.scene.receivers if not isinstance(r, str) or canonical(r) is None]
    if unknown:
        return [ConfigError(f"{where}: scene.receivers: unknown receiver {unknown[0]!r}; known: {', '.join(NAMES)}")]
    seen = [canonical(n) for n in names]
    if len(set(seen)) != len(seen):
        dup = next(n for n in seen if seen.count(n) > 1)
        return [ConfigError(f"{where}: scene.receivers names {dup!r} twice (scene.format is heard anyway); name "
                            f"each receiver once")]
    if cfg.room.bank:
        base = {receiver(n).bank_format for n in names}
        if len(base) > 1:
            return [ConfigError(f"{where}: scene.format and scene.receivers need RIR banks of {sorted(base)}; a "
                                f"bank holds one receiver's RIRs: keep the receivers one bank serves (e.g. foa "
                                f"and stereo)")]
    specs = [receiver(n) for n in names]
    if not any(s.configured for s in specs):
        for key in ("capsules", "patterns", "orientations"):
            if getattr(a, key):
                out.append(ConfigError(f"{where}: array.{key} is set but scene.format = {fmt!r}; it describes a "
                                       f"custom array: set scene.format = \"custom\" or remove array.{key}"))
    else:
        out += _capsule_problems(a, where)
    ears = any(s.model == ReceiverModel.HRTF for s in specs)
    if ears and not a.hrtf:
        out.append(ConfigError(f"{where}: the binaural receiver needs array.hrtf = \"FILE.sofa\" (a SOFA "
                               f"SimpleFreeFieldHRIR file, e.g. the MIT KEMAR set)"))
    if not ears and a.hrtf:
        out.append(ConfigError(f"{where}: array.hrtf is set but scene.format = {fmt!r} has no ears; set "
                               f"scene.format = \"binaural\" or remove array.hrtf"))
    return out


def _capsule_problems(a, where: str) -> list[ConfigError]:
    caps = a.capsules
    if not caps:
        return [ConfigError(f"{where}: scene.format = \"custom\" needs array.capsules = [[x, y, z], ...] (metres, "
                            f"array frame: x front, y left, z up)")]
    if len(caps) > MAX_CHANNELS:
        return [ConfigError(f"{where}: array.capsules has {len(caps)} capsules; at most {MAX_CHANNELS} are "
                            f"supported")]
    for k, c in enumerate(caps):
        if not (isinstance(c, (list, tuple)) and len(c) == 3
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in c)):
            return [ConfigError(f"{where}: array.capsules[{k}] = {_shown(c)} is not [x, y, z] in metres (three "
                                f"finite numbers)")]
        if max(abs(v) for v in c) > 1.0:
            return [ConfigError(f"{where}: array.capsules[{k}] = {_shown(c)} is more than 1 m from the array "
                                f"centre; capsule positions are metres (0.05, not 50)")]
    n = len(caps)
    pats = a.patterns
    if pats and len(pats) not in (1, n):
        return [ConfigError(f"{where}: array.patterns has {len(pats)} entries for {n} capsules; give one for all "
                            f"or one per capsule")]
    bad = [p for p in pats if p not in PATTERN_ALPHA]
    if bad:
        return [ConfigError(f"{where}: array.patterns: unknown pattern {bad[0]!r}; choose among "
                            f"{', '.join(PATTERN_ALPHA)}")]
    ors = a.orientations
    if ors and len(ors) not in (1, n):
        return [ConfigError(f"{where}: array.orientations has {len(ors)} entries for {n} capsules; give one "
                            f"[azimuth, elevation] for all or one per capsule")]
    for k, o in enumerate(ors):
        if not (isinstance(o, (list, tuple)) and len(o) == 2 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in o)
                and -90.0 <= o[1] <= 90.0):
            return [ConfigError(f"{where}: array.orientations[{k}] = {_shown(o)} is not [azimuth, elevation] in "
                                f"degrees (elevation within ±90)")]
    resolved = custom_capsules(caps, pats, ors)
    omni = [p == "omni" for p in resolved.get("patterns", ("omni",) * n)]
    axes = resolved.get("orientations", ((0.0, 0.0),) * n)
    for i in range(n):
        for j in range(i + 1, n):
            if math.dist(caps[i], caps[j]) < 1e-3 and (omni[i] or omni[j] or tuple(axes[i]) == tuple(axes[j])):
                # a coincident pair is only a pair if both are directional and aimed apart (XY stereo)
                return [ConfigError(f"{where}: array.capsules[{i}] and [{j}] are {math.dist(caps[i], caps[j]) * 1000:.2g} "
                                    f"mm apart: the same capsule twice; space them (at least 1 mm) or make them "
                                    f"directional capsules aimed apart (array.patterns, array.orientations)")]
    return []


def _shown(v) -> str:
    return repr(list(v) if isinstance(v, tuple) else v)


def hrtf_problem(cfg: Config) -> ConfigError | None:
    """A binaural receiver's HRTF that cannot be used: missing, not a SOFA
    SimpleFreeFieldHRIR file (acoustics/hrtf.py says what is wrong), one line."""
    if all(receiver(n).model != ReceiverModel.HRTF for n in receiver_names(cfg)) or not cfg.array.hrtf:
        return None
    path = os.path.abspath(os.path.expanduser(cfg.array.hrtf))
    problem = path_problem(path)
    if problem and problem != "does not exist":
        return ConfigError(f"array.hrtf: {path} {problem}; give the path of a SOFA HRTF file (SimpleFreeFieldHRIR)")
    if not os.path.isfile(path):
        return ConfigError(f"array.hrtf: {path} not found; give the path of a SOFA HRTF file (SimpleFreeFieldHRIR)")
    from ..acoustics.hrtf import read_hrtf  # h5py and scipy.fft: only binaural configs pay for them

    try:
        read_hrtf(path, cfg.audio.fs)
    except OSError as e:
        return ConfigError(f"array.hrtf: {path}: cannot read it ({e.strerror or e})")
    except ConfigError as e:
        return e
    return None
