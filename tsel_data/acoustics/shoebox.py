"""The project's shoebox simulator: calibrated image sources, diffuse late tail, FOA.

``shoebox_rirs(room, array, points, fs, method, seed)`` returns RIRs [S, C, L] with
sample 0 at the emission time and the direct path of a point r metres away at
r / c · fs samples with amplitude 1 / (4π r) (the free-field Green's function; the
pyroomacoustics method is put on the same scale, acoustics/pyroom.py).

Methods (docs/acoustics.md):

- ``ism``: every image source up to the RIR length, one reflection coefficient
  β = exp(-a) for all walls; ``a`` is fitted so that the T30 of the first point's
  channel-0 response equals ``room.rt60`` (its image amplitudes per arrival sample and
  reflection order are tabulated once, so each fit step is one matrix-vector product).
- ``hybrid`` (default): image sources up to a transition time (80 ms, later if a source
  is far), then Gaussian noise with diffuse-field coherence (late.py) whose energy
  envelope continues the expected image-source energy at the transition and decays with
  exactly ``room.rt60``. A 10 ms power-complementary cross-fade joins them.

Receivers: each image source reaches the channels as the receiver's capsule model says
(capsules.py: spaced capsules, omni or first order; FOA with the ACN/SN3D gains of its
direction in the array frame; capsules on a rigid sphere; ears through an HRTF; channels
mixed from another receiver), and the tail has the receiver's diffuse-field statistics
(omni coherence sinc(kd); FOA uncorrelated W, Y, Z, X with energies 1 : 1/3 : 1/3 : 1/3).
Pure numpy: no pyroomacoustics code, threads or global random state.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..choices import RirMethod
from ..core.geometry import SOUND_SPEED
from ..errors import GeometryError
from .base import RirSet
from .capsules import capsule_model
from .highpass import butter2_highpass, sosfilt
from .image_paths import image_groups, n_groups
from .knots import batched, knot_parts
from .ism import FD_TAPS, decay_model, fd_energy_gain, image_chunks, model_edc
from .metrics import decay_time, t30

METHODS = (RirMethod.HYBRID, RirMethod.ISM)
TRANSITION = 0.080  # s, hybrid: image sources before, diffuse tail after
FADE = 0.010  # s, cross-fade width around the transition
HIGHPASS = 20.0  # Hz, DC blocker on the image-source part (see _dc_blocker)


def shoebox_rirs(
    room,
    array,
    points: np.ndarray,
    fs: int,
    method: str = "hybrid",
    seed: int = 0,
    *,
    max_order: int | None = None,
    transition: float | None = None,
    length: float | None = None,
    one_source: bool = False,
    tail_apart: bool = False,
    groups: int = 1,
    image_highpass: bool = True,
) -> RirSet:
    """RIRs from room-frame ``points`` [S, 3] (m) to the channels of ``array``.

    room: :class:`~tsel_data.core.geometry.Room` (dims m, rt60 s). array:
    :class:`~tsel_data.core.geometry.ArrayPose`. fs: Hz. method: ``hybrid`` | ``ism``. seed:
    the late tail's noise (numpy Generator; ``ism`` is deterministic anyway).
    max_order: keep image sources with at most this many reflections (0 = free field);
    a finite order also drops the hybrid tail. transition: hybrid transition time (s),
    default max(80 ms, latest direct path + 20 ms). length: RIR length (s), default the
    latest direct path + rt60 (the decay has reached about -60 dB). one_source: the
    points are knots of one moving source, so they share one tail realisation
    (independent tails, crossfaded between knots, would dip 3 dB at every midpoint).
    tail_apart: with ``one_source``, return that tail apart (``RirSet.tail`` [C, L]) and
    only the image-source parts in ``rirs`` [S, C, L_img] (L_img ≈ the transition + 50 ms).
    groups: with ``tail_apart``, split each knot's image-source part into at most this
    many groups of images that move alike (image_paths.py): ``rirs`` [S, G·C, L_img],
    group-major, and ``RirSet.delays`` [S, G, C] each group's delay trajectory, to align
    the group by between knots. image_highpass: False (with ``tail_apart``): the
    image parts without the DC blocker, which ``RirSet.highpass`` holds for the caller to
    apply once to what it renders from them (it commutes with the time-varying render),
    and only as long as the last image (no room for the blocker's response): knots with
    groups are then simulated all at once (knots.py).

    Returns a :class:`RirSet` with float32 rirs [S, C, L] and ``rt60_measured`` = T30 of
    point 0, channel 0 (omni / W), or None when the response is too short to measure.
    """
    if method not in METHODS:
        raise ValueError(f"unknown shoebox method {method!r}; expected one of {METHODS}")
    dims = np.asarray(room.dims, dtype=np.float64)
    rt60 = float(room.rt60)
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    if not (np.all(dims > 0) and rt60 > 0):
        raise GeometryError(f"room {dims.tolist()} with RT60 {rt60} s: dimensions and RT60 must be positive")
    centre = np.asarray(array.centre, dtype=np.float64)
    model = capsule_model(array, fs)  # how the receiver's channels hear each image (capsules.py)
    mics = model.points  # [C, 3] capsules (the centre of a coincident receiver), room frame
    _check_points(points, mics, dims)
    c = SOUND_SPEED

    dist = np.linalg.norm(points - centre, axis=1)
    t_direct = float(dist.max()) / c
    if length is None:
        length = t_direct + (rt60 if max_order != 0 else 0.0) + 0.005
    n_len = int(np.ceil(length * fs))
    a = ism_absorption(dims, rt60)
    aperture = float(np.linalg.norm(mics - centre, axis=1).max())
    with_tail = method == "hybrid" and max_order is None
    if with_tail:
        t_mix = transition if transition is not None else max(TRANSITION, t_direct + 0.020)
        with_tail = t_mix - FADE / 2 < n_len / fs
    if with_tail:
        t_img = t_mix + FADE / 2
    else:
        t_img = n_len / fs
        if method == "ism" and max_order is None:
            a = fit_ism_absorption(dims, rt60, points[0], model.reference, fs, n_len, a)
    radius = c * t_img + aperture
    fade = (t_mix, FADE) if with_tail else None

    apart = tail_apart and one_source and with_tail
    filtered = image_highpass or not apart
    # the image part only needs to be as long as the last image, plus the interpolator
    # and (when filtered here) 50 ms for the DC blocker's response (time constant ~8 ms) to die out
    n_img = min(n_len, int(np.ceil((t_img + (0.05 if filtered else 0.0)) * fs)) + FD_TAPS)
    C = model.n_channels
    # a group's delay per channel, from its capsule; channels mixed from others (or
    # coincident ones) all take the delay at the centre
    where = mics if len(mics) == C else np.repeat(centre[None], C, axis=0)
    grouped = image_groups(dims, points, where, centre, fs, radius, np.exp(-a), min(groups, n_groups(
        len(points), C, n_img))) if apart and groups > 1 and len(points) > 1 else None
    G = grouped.n_groups if grouped else 1
    rirs = np.zeros((len(points), G * C, n_img if apart else n_len), dtype=np.float32)
    if grouped is not None and not filtered and batched(model):
        rirs[:] = knot_parts(model, grouped, centre, radius, a, fade, n_img)
    for s, p in enumerate(points if filtered or grouped is None or not batched(model) else ()):
        if grouped is None:
            grid = model.new_grid(n_img)
            for pos, order in image_chunks(dims, p, centre, radius, max_order):
                model.add(grid, pos, np.exp(-a * order), fade)
            rirs[s, :, :n_img] = sosfilt(_dc_blocker(fs), model.render(grid)) if filtered else model.render(grid)
            continue
        chunks = [(pos, np.exp(-a * order), grouped.of(key)) for pos, order, key in
                  image_chunks(dims, p, centre, radius, max_order, keys=True)]
        parts = np.empty((G * C, n_img))
        for g in range(G):
            grid = model.new_grid(n_img)  # one grid, reused: each group is rendered before the next
            for pos, amp, group in chunks:
                mine = group == g
                model.add(grid, pos[mine], amp[mine], fade)
            parts[g * C:(g + 1) * C] = model.render(grid)
        rirs[s] = sosfilt(_dc_blocker(fs), parts) if filtered else parts

    tail, first = None, rirs[0, 0]
    if with_tail:
        late = _late_tail(np.random.default_rng(seed), dims, a, rt60, model, fs, n_len, t_mix,
                          1 if one_source else len(points))
        if apart:
            tail = late[0]
            first = tail[0].copy()  # point 0's whole response: the same float32 sums as rirs += late
            image = rirs[0, ::C].sum(axis=0) if G > 1 else rirs[0, 0]
            if not filtered:  # measured as it sounds: blocked, with room for the blocker's response
                image = sosfilt(_dc_blocker(fs), np.r_[image, np.zeros(min(n_len - n_img, int(0.05 * fs)))])
            first[:len(image)] += image
        else:
            rirs += late
    measured = t30(first, fs) if max_order != 0 else float("nan")
    return RirSet(rirs, None if np.isnan(measured) else measured, tail,
                  grouped.delays if grouped is not None else None, None if filtered else _dc_blocker(fs))


# --- absorption ---------------------------------------------------------------------
def ism_absorption(dims, rt60: float, c: float = SOUND_SPEED) -> float:
    """Image-source attenuation a (per reflection, β = exp(-a)) whose expected energy
    decay (:func:`~tsel_data.acoustics.ism.decay_model`) has a T30 of ``rt60``.

    The model depends on time only through x = 2 a c t, so T30 = X30 / (2 a c) where X30
    is the T30 of the model's Schroeder curve measured in x; one evaluation fixes a.
    """
    dims = np.asarray(dims, dtype=np.float64)
    # g(u) ≥ 1 / Lmax, so by x = 10 ln(10) Lmax the curve is well below -35 dB
    x = np.linspace(0.0, 10.0 * np.log(10.0) * dims.max(), 256)
    curve = model_edc(dims, x)
    x30 = decay_time(10.0 * np.log10(curve / curve[0]), x[1] - x[0])
    # x = 2 a c t: the model's T30 in x-units is X30, so in seconds X30 / (2 a c)
    return float(x30 / (2.0 * c * rt60))


def fit_ism_absorption(dims, rt60: float, source, receiver, fs: int, n_len: int, a0: float,
                       c: float = SOUND_SPEED) -> float:
    """Refine ``a0`` on the actual image set from ``source`` to ``receiver`` (room frame).

    The response for any a is ``h = A @ exp(-a n)`` with ``A[k, n] = Σ 1 / (4π r)`` over
    the images of order n arriving at sample k (nearest sample), built once. Summing
    amplitudes, not energies, keeps the coherent coincidences of a specular box (in a
    flat room the floor/ceiling image pairs of the late, near-horizontal field arrive
    together and add in phase), which slow its decay by ~5 %. Each step is one
    matrix-vector product, the DC blocker and a Schroeder fit; the fixed-point update
    a ← a · T30(a) / rt60 (T30 ∝ 1/a in the continuum model) converges in 2-4 steps.
    """
    radius = c * n_len / fs
    # an image within `radius` has at most radius / L + 2 reflections per axis
    n_cols = int(sum(np.ceil(radius / d) + 2 for d in np.asarray(dims, dtype=np.float64))) + 1
    amp = np.zeros(n_len * n_cols)
    for pos, order in image_chunks(dims, source, receiver, radius):
        r = np.maximum(np.linalg.norm(pos - receiver, axis=1), 1e-3)
        k = np.minimum(np.rint(r / c * fs).astype(np.int64), n_len - 1)
        amp += np.bincount(k * n_cols + order, 1.0 / (4 * np.pi * r), minlength=n_len * n_cols)
    amp = amp.reshape(n_len, n_cols)
    orders = np.arange(n_cols)
    sos = _dc_blocker(fs)
    a = a0
    for _ in range(6):
        measured = t30(sosfilt(sos, amp @ np.exp(-a * orders)), fs)
        if not np.isfinite(measured):
            break
        ratio = measured / rt60
        a *= ratio
        if abs(ratio - 1.0) < 0.002:
            break
    return float(a)


# --- rendering helpers ----
@lru_cache(maxsize=8)
def _dc_blocker(fs: int) -> np.ndarray:
    """2nd-order Butterworth high-pass at HIGHPASS Hz (second-order sections), causal.

    All image sources of rigid-phase walls have the same sign, so once there are many
    per sample their sum carries a slowly varying positive offset whose energy grows
    with the image density (∝ t²) and lengthens T30 by 20-30 %. Real walls and
    microphones have no such DC path; Allen & Berkley (1979) high-pass their image RIRs
    for the same reason. Causal, so sample 0 stays the emission time (the direct path
    peak is scaled by b0 ≈ 0.996 at 24 kHz). Designed and run without scipy.signal
    (highpass.py), the same numbers as its butter and sosfilt."""
    return butter2_highpass(HIGHPASS, fs)


def _late_tail(rng, dims, a, rt60, model, fs, n_len, t_mix, n_points) -> np.ndarray:
    """Diffuse tails [S, C, n_len] (float32): zero before the cross-fade, then noise with
    variance η E(t_mix) / fs at t_mix decaying by 60 dB per rt60, faded in by sin.

    E(t) = c / (16 π² V) ∫ exp(-2 a c t g(u)) dΩ is the expected image energy rate
    (ism.decay_model), η the share of an impulse's energy the fractional-delay
    interpolator keeps, so the tail continues the image sources without a level step.
    """
    c = SOUND_SPEED
    start = int(np.floor((t_mix - FADE / 2) * fs))
    n = n_len - start
    t = (start + np.arange(n)) / fs
    e_mix = c / (16 * np.pi**2 * np.prod(dims)) * float(decay_model(dims, 2 * a * c * t_mix))
    rho = np.clip((t - (t_mix - FADE / 2)) / FADE, 0.0, 1.0)
    env = np.sqrt(fd_energy_gain() * e_mix / fs) * 10.0 ** (-3.0 * (t - t_mix) / rt60) * np.sin(0.5 * np.pi * rho)
    noise = model.diffuse_noise(rng, n_points, n)  # the receiver's diffuse-field statistics (capsules.py)
    out = np.zeros((n_points, model.n_channels, n_len), dtype=np.float32)
    out[..., start:] = noise * env
    return out


def _check_points(points: np.ndarray, mics: np.ndarray, dims: np.ndarray) -> None:
    if points.ndim != 2 or points.shape[1] != 3:
        raise GeometryError(f"source points must have shape [S, 3]; got {list(points.shape)}")
    for p in points:
        if np.any(p <= 0) or np.any(p >= dims):
            raise GeometryError(f"source at {np.round(p, 3).tolist()} is not inside room {dims.tolist()}")
        if np.min(np.linalg.norm(mics - p, axis=1)) < 0.01:
            raise GeometryError(f"source at {np.round(p, 3).tolist()} is within 1 cm of a microphone; move it away")
    lo, hi = mics.min(axis=0), mics.max(axis=0)
    if np.any(lo <= 0) or np.any(hi >= dims):
        raise GeometryError(
            f"the array's capsules span {np.round(lo, 3).tolist()}–{np.round(hi, 3).tolist()}, "
            f"outside room {dims.tolist()}; move the array inside"
        )
