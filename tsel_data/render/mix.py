"""Render a scene recipe: dry clips -> RIRs -> spatial images -> mix at the recipe's levels
-> per-frame labels.

Levels: every gain is set from *active-frame* RMS (audio.active_rms), never from a
clip's length: the target's image at the array is put at ``target_level_dbfs`` and
each interferer's image ``tir_db`` below it. If the mix would clip, everything is scaled
down together and the scaling is recorded (``levels.normalisation_db``).

Labels: frame k covers [k·hop, (k+1)·hop); its position is the source's position at
the frame centre, in the array frame.

The record (:class:`~tsel_data.store.records.SceneRecord`) says everything else about
the scene: room, array pose, clips, placements, levels.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..acoustics import simulate_rirs
from ..acoustics.capsules import capsule_model
from ..acoustics.descriptors import describe_rir
from ..acoustics.diffuse import diffuse_image
from ..acoustics.highpass import sosfilt
from ..acoustics.image_paths import GROUPS
from ..banks.scenes import open_bank_cached
from ..choices import Spatial
from ..core.geometry import cart_to_sph, frame_centres
from ..corpus.ambience import omni_energy
from ..corpus.audio import active_rms, db, frame_activity, load_clip_cached
from ..dsp.hardware import clock_warp, self_noise, through_capsules
from ..dsp.timevarying import render_moving, render_static
from ..errors import AudioError, BankError
from ..scene.motion import motion_class
from ..scene.queries import Truth, decide
from ..scene.recipe import BankRef, Roots, SceneRecipe, array_frame_position_at
from ..store.records import (LABEL_DECIMALS, ArrayRecord, HardwareRecord, LevelsRecord, NoiseRecord, RoomRecord,
                             SceneRecord, SourceRecord, label_list)
from ..store.scene import Scene
from .noise import noise_image, noise_gain, noise_level_dbfs

# The mix's peak is kept below full scale, so 16-bit exports do not clip: if the mixed
# scene would exceed it, every source is scaled down together (levels.normalisation_db).
PEAK_LIMIT = 0.99
# an image this far below its dry clip (-200 dB) went through RIRs that are damage, not a room
SILENT_IMAGE = 1e-10


def convolve(signals, rirs, n_out: int, out=None) -> np.ndarray:
    """Static FFT convolution of each source with its RIRs, kept to ``n_out`` samples.

    signals: S float32 [T]; rirs: S float32 [C, L] (arrays [S, T], [S, C, L] or sequences)
    -> float32 [S, C, n_out], where out[s, c] = (signals[s] * rirs[s, c])[:n_out]; into
    ``out`` when given ([S, C, n_out], or S arrays [C, n_out]: rows of a scene's images).
    One implementation for the whole package: timevarying.render_static (batched
    overlap-add, float32).
    """
    if out is None:
        out = np.empty((len(signals), rirs[0].shape[0], n_out), dtype=np.float32)
    for x, h, o in zip(signals, rirs, out):
        render_static(x, h, out=o)
    return out


def frame_times(recipe: SceneRecipe) -> np.ndarray:
    """Label frame centres (s): (k + 0.5)·hop for k < round(duration / hop)."""
    return frame_centres(recipe.n_frames, recipe.label_hop)


def source_labels(recipe: SceneRecipe, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(azimuth, elevation, distance) [F] of source k in the array frame; NaN if positionless."""
    s = recipe.sources[k]
    f = recipe.n_frames
    if s.spatial != Spatial.DIRECTIONAL:
        nan = np.full(f, np.nan, dtype=np.float32)
        return nan, nan.copy(), nan.copy()
    if s.bank is not None:
        p = s.bank.positions_at(frame_times(recipe))
        return p[:, 0].astype(np.float32), p[:, 1].astype(np.float32), p[:, 2].astype(np.float32)
    az, el, dist = cart_to_sph(array_frame_position_at(recipe, s, frame_times(recipe)))
    return az.astype(np.float32), el.astype(np.float32), dist.astype(np.float32)


def spatial_images(recipe: SceneRecipe, dry: np.ndarray, array=None, keep: dict | None = None
                   ) -> tuple[np.ndarray, float | None]:
    """Each source's image at the array, unscaled: float32 [S, C, T]; and the measured RT60.
    ``array``: one of the recipe's receivers (default the first, ``recipe.array``).
    ``keep``: filled with {source: its RIR [C, L]} of static simulated sources,
    {source: [RIR at each knot]} of bank sources and {source: its knots' RirSet} of
    simulated moving ones (what :func:`source_descriptors` measures).

    Static simulated sources share one batched RIR computation and convolution; moving
    and bank sources go through the time-varying renderer (dsp/timevarying.py); additive
    sources are the dry clip on every omni channel (FOA: on W only, since equal gains on
    Y, Z, X would be a direction); diffuse ones are the clip as a diffuse field with the
    receiver's diffuse-field cross-spectra (acoustics/diffuse.py), drawn from the scene's seed.
    """
    fs, n = recipe.fs, recipe.n_samples
    array = recipe.array if array is None else array
    # written once: each source below fills its whole image, zeros included (a zero-filled
    # buffer cost a pass over [S, C, T], and a convolution into a buffer of its own a copy)
    images = np.empty((len(recipe.sources), array.n_channels, n), dtype=np.float32)
    rt60 = None
    static = [k for k, s in enumerate(recipe.sources)
              if s.spatial == Spatial.DIRECTIONAL and s.bank is None and not s.path]
    if static:
        pts = np.array([recipe.sources[k].position for k in static], dtype=np.float64)
        rs = simulate_rirs(recipe.room, array, pts, fs, method=recipe.rir_method, seed=recipe.seed)
        rt60 = rs.rt60_measured
        convolve([dry[k] for k in static], rs.rirs, n, out=[images[k] for k in static])
        if keep is not None:
            keep.update((k, rs.rirs[j]) for j, k in enumerate(static))
    for k, s in enumerate(recipe.sources):
        if s.spatial == Spatial.ADDITIVE:
            _additive(images[k], dry[k], array.spec.additive_gains(array.n_channels))
        elif s.spatial == Spatial.DIFFUSE:
            images[k] = diffuse_image(dry[k], fs, capsule_model(array, fs).diffuse_csd,
                                      np.random.default_rng([recipe.seed, k]))
        elif s.path:
            kept = [] if keep is not None else None
            images[k], measured = path_image(recipe.room, array, s.path, dry[k], fs, recipe.rir_method,
                                             recipe.seed + 1 + k, rirs_to=kept)
            rt60 = measured if rt60 is None else rt60
            if kept:
                keep[k] = kept[0]
        elif s.bank is not None:
            b = s.bank
            # a mixed receiver (stereo from FOA) mixes its base's measured RIRs
            rirs = [array.spec.mixed(r) for r in _bank(recipe).views(b.room, b.trajectory, b.indices)]
            if keep is not None:
                keep[k] = rirs
            if len(rirs) == 1:
                convolve(dry[k:k + 1], rirs[:1], n, out=images[k:k + 1])
            else:
                images[k] = render_moving(dry[k], rirs, np.asarray(b.times), fs)[:, :n]
    return images, rt60


def _additive(image: np.ndarray, dry: np.ndarray, gains: np.ndarray) -> None:
    """An unspatialised source on the receiver's omni channels (``spec.additive``: every
    capsule, W alone for FOA); channels of gain 0 stay exactly zero."""
    for ch, g in enumerate(gains):
        if g == 1.0:
            image[ch] = dry
        elif g != 0.0:
            image[ch] = dry * np.float32(g)
        else:
            image[ch] = 0.0


def path_image(room, array, path, dry: np.ndarray, fs: int, method: str, seed: int,
               rirs_to: list | None = None) -> tuple[np.ndarray, float | None]:
    """A simulated moving source's image [C, len(dry)] and the measured RT60 of its first
    knot: ``path`` knots (t, x, y, z), room frame. The knots' image-source parts go through
    the time-varying renderer, in groups of images that move alike, each aligned by its
    own delay between knots (acoustics/image_paths.py); the late tail they share (hybrid)
    does not move with the source, so it is one static convolution. ``rirs_to``: the
    knots' RirSet is appended to it."""
    knots = np.asarray(path, dtype=np.float64)
    rs = simulate_rirs(room, array, knots[:, 1:], fs, method=method, seed=seed, one_source=True, tail_apart=True,
                       groups=GROUPS, image_highpass=False)
    n = len(dry)
    image = moving_image_part(dry, rs, knots[:, 0], fs, n)
    if rs.tail is not None:
        image += render_static(dry, rs.tail)[:, :n]
    if rirs_to is not None:
        rirs_to.append(rs)
    return image, rs.rt60_measured


def knot_rir(rs, j: int, fs: int) -> np.ndarray:
    """The whole RIR [C, L] of knot ``j`` of a moving source's RirSet: its image groups
    summed, through the DC blocker they still need, plus the tail the knots share."""
    h = rs.rirs[j].astype(np.float64)
    if rs.delays is not None:
        h = h.reshape(rs.delays.shape[1], -1, h.shape[-1]).sum(axis=0)
    if rs.highpass is not None:  # room for the blocker's response, as shoebox.py leaves it
        h = sosfilt(rs.highpass, np.pad(h, ((0, 0), (0, int(0.05 * fs)))))
    if rs.tail is None:
        return h
    out = np.zeros((h.shape[0], max(h.shape[1], rs.tail.shape[1])))
    out[:, :rs.tail.shape[1]] = rs.tail
    out[:, :h.shape[1]] += h
    return out


def moving_image_part(dry: np.ndarray, rs, times: np.ndarray, fs: int, n: int | None = None) -> np.ndarray:
    """The knots' RIRs ``rs`` (a RirSet, rirs without the shared tail) rendered along the
    path: float32 [C, n] (default: the whole render, ≥ len(dry)); image groups
    (``rs.delays``) each aligned by its own delay; the DC blocker the parts still need
    (``rs.highpass``) applied once, to the render (it commutes with it)."""
    if rs.delays is None:
        image = render_moving(dry, rs.rirs, times, fs)
    else:  # the groups in one render, each with its warp, summed before the inverse transforms
        G = rs.delays.shape[1]
        image = render_moving(dry, rs.rirs, times, fs, delays=rs.delays.reshape(len(times), -1), fold=G)
    image = image[:, :n]
    if rs.highpass is not None:
        image = sosfilt(rs.highpass, image).astype(np.float32)
    return image


@dataclass(frozen=True)
class MixParts:
    """What a scene's mixture is made of (:func:`mix_parts`).

    active: bool [S, F]. images: float32 [S, C, T], each source's image at the array,
    unscaled. noise: each of the recipe's noises as mixed (:class:`MixedNoise`). gains: [S], each image's gain before ``norm``, the gain applied to the
    whole mix against clipping. levels: [S] active-frame RMS of the unscaled images.
    peak: the mix's peak before ``norm``. mix: float32 [C, T], the scene's audio.
    rt60_measured: s, or None. others: the recipe's further receivers (``recipe.receivers``),
    each (images, mix) with the same gains and ``norm`` (levels are set on the first
    receiver; ``norm`` keeps every receiver's mix below full scale). hardware: each
    receiver's microphones as built (``recipe.hardware``; empty: ideal), already in ``mix``
    and the others' mixes; the stems go through them too. descriptors: with
    ``recipe.descriptors``, each source's (:func:`source_descriptors`), else empty.
    """

    active: np.ndarray
    images: np.ndarray
    gains: np.ndarray
    norm: float
    levels: np.ndarray
    peak: float
    mix: np.ndarray
    rt60_measured: float | None
    others: tuple = ()
    noise: tuple = ()
    hardware: tuple = ()
    fs: int = 0
    descriptors: tuple = ()

    def stems(self, receiver: int = 0) -> np.ndarray:
        """float32 [S, C, T]: each source alone as it sounds in the mix of receiver
        ``receiver`` (0: the first; with :meth:`noise_stem` they add up to its mix within
        float32 rounding), through the receiver's hardware when it has any."""
        images = self.images if receiver == 0 else self.others[receiver - 1][0]
        stems = images * (self.gains * self.norm).astype(np.float32)[:, None, None]
        hw = self.hardware[receiver] if self.hardware else None
        if hw is not None:
            stems = np.stack([clock_warp(through_capsules(x, hw, self.fs), hw, self.fs) for x in stems])
        return stems

    def noise_stem(self, receiver: int = 0) -> np.ndarray | None:
        """float32 [C, T]: everything but the sources (``[noise]``, and the capsules' own
        self-noise) as it sounds in the mix, or None."""
        hw = self.hardware[receiver] if self.hardware else None
        noise = self_noise(hw, self.images.shape[-1], self.fs) if hw is not None else None
        if not self.noise and noise is None:
            return None
        if not self.noise:
            return clock_warp(noise, hw, self.fs)
        bed = sum(n.images[receiver] for n in self.noise) * np.float32(self.norm)
        if hw is None:
            return bed
        bed = through_capsules(bed, hw, self.fs)
        return clock_warp(bed if noise is None else bed + noise, hw, self.fs)


@dataclass(frozen=True)
class MixedNoise:
    """One noise of a scene as mixed: its item, its gain, each receiver's scaled image
    [C, T] before ``norm`` (the first receiver's first), and its SNR as measured."""

    item: object
    gain: float
    images: tuple
    snr_db: float | None


def mix_parts(recipe: SceneRecipe) -> MixParts:
    """Load the clips, render each source's image and set the levels (see the module
    docstring): every step of :func:`render_scene` but the labels and the record."""
    fs, hop, nf = recipe.fs, recipe.label_hop, recipe.n_frames
    dry = np.stack([_started(load_clip_cached(s.audio, fs, recipe.duration, s.offset), s.start, fs)
                    for s in recipe.sources])
    active = np.stack([frame_activity(x, fs, hop, nf, recipe.activity_threshold_db) for x in dry])

    rirs = {} if recipe.descriptors else None
    images, rt60_measured = spatial_images(recipe, dry, keep=rirs)

    level_ch = recipe.array.spec.level_slice()  # the "omni energy": W for FOA, every capsule of an array
    levels = np.array([active_rms(images[k, level_ch], active[k], fs, hop) for k in range(len(images))])
    for k, s in enumerate(recipe.sources):
        sounding = float(np.max(np.abs(dry[k])))
        if not np.isfinite(levels[k]) or (levels[k] <= SILENT_IMAGE * sounding and sounding > 0):
            _blame_rirs(recipe, k)
        if levels[k] <= 0:
            # a silent source would leave a query describing nothing audible
            raise AudioError(f"{recipe.scene_id}: source {k} ({s.clip_id}, {s.audio}) is silent in the "
                             f"{recipe.duration:g} s the scene uses; set corpus.check = \"full\" so such clips "
                             f"are found before planning, or remove it from the manifest")
    gains = source_gains(recipe, dry, active, levels)
    mix = np.tensordot(gains.astype(np.float32), images, axes=1)
    others = []
    for pose in recipe.receivers:  # heard where the first one is, at the same gains
        imgs, _ = spatial_images(recipe, dry, pose)
        others.append((imgs, np.tensordot(gains.astype(np.float32), imgs, axes=1)))
    noise = tuple(_mixed_noise(recipe, item, images[0] * np.float32(gains[0]), level_ch) for item in recipe.noise)
    for nz in noise:
        mix += nz.images[0]
        for (_, m), img in zip(others, nz.images[1:]):
            m += img
    hw = recipe.hardware
    if hw:  # each receiver's capsules: after the room, before the guard against clipping
        mix = through_capsules(mix, hw[0], fs)
        others = [(imgs, through_capsules(m, h, fs)) for (imgs, m), h in zip(others, hw[1:])]
    peak = float(np.max(np.abs(mix))) if mix.size else 0.0
    top = max([peak] + [float(np.max(np.abs(m))) for _, m in others if m.size])
    norm = PEAK_LIMIT / top if top > PEAK_LIMIT else 1.0
    mix *= np.float32(norm)
    for _, m in others:
        m *= np.float32(norm)
    if hw:  # then their self-noise, at its own level, and their clocks
        mix = _self_noise_and_clock(mix, hw[0], fs)
        others = [(imgs, _self_noise_and_clock(m, h, fs)) for (imgs, m), h in zip(others, hw[1:])]
    described = source_descriptors(recipe, rirs, active) if recipe.descriptors else ()
    return MixParts(active, images, gains, norm, levels, peak, mix, rt60_measured, tuple(others), noise, hw, fs,
                    described)


def _self_noise_and_clock(mix: np.ndarray, hw, fs: int) -> np.ndarray:
    noise = self_noise(hw, mix.shape[-1], fs)
    if noise is not None:
        mix += noise
    return clock_warp(mix, hw, fs)


# a moving simulated source is measured on its knot nearest the middle of its sounding
# frames when that knot is at most this far from it (half plan.placement's longest hop)
KNOT_NEAR_S = 0.05


def source_descriptors(recipe: SceneRecipe, rirs: dict, active: np.ndarray) -> tuple:
    """Each source's acoustic descriptors (acoustics/descriptors.py) at the first receiver,
    from the RIRs it was rendered with (``rirs``, :func:`spatial_images`' ``keep``); None
    for positionless sources. A moving source is measured where it is in the middle of the
    frames it sounds in: at the knot nearest then (a simulated one: that knot's image part
    and the tail its knots share, :func:`knot_rir`, when the knot is within
    :data:`KNOT_NEAR_S`; else a static RIR simulated there, the same room, method and seed)."""
    out = []
    level_ch = recipe.array.spec.level_slice()
    for k, s in enumerate(recipe.sources):
        if s.spatial != Spatial.DIRECTIONAL:
            out.append(None)
            continue
        heard = np.nonzero(active[k])[0]
        t = (heard[0] + heard[-1] + 1) / 2 * recipe.label_hop if len(heard) else recipe.duration / 2
        if s.path:
            times = np.asarray(s.path)[:, 0]
            j = int(np.argmin(np.abs(times - t)))
            if abs(times[j] - t) <= KNOT_NEAR_S:  # a planned path's knot (≤ 100 ms apart): where the source is
                rir = knot_rir(rirs[k], j, recipe.fs)
            else:  # knots far apart (a path by hand): a static RIR simulated where the source is then
                rir = simulate_rirs(recipe.room, recipe.array, s.position_at(t)[None], recipe.fs,
                                    method=recipe.rir_method, seed=recipe.seed + 1 + k).rirs[0]
        elif s.bank is not None:
            rir = rirs[k][int(np.argmin(np.abs(np.asarray(s.bank.times) - t)))]
        else:
            rir = rirs[k]
        out.append(describe_rir(rir, recipe.fs, level_ch))
    return tuple(out)


def source_gains(recipe: SceneRecipe, dry: np.ndarray, active: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Each source's gain on its unscaled image [S] (before the clipping guard).

    ``tir`` (sources without ``power_db``): the target's image at ``target_level_dbfs``,
    each interferer's ``tir_db`` below it. ``distance`` (sources with ``power_db``): the
    dry clip at unit active level times 10^(power_db / 20) is the source's sound at 1 m
    (the image's direct path falls as 1 / r), so its level at the array follows from its
    distance and the room; one gain for all then puts the target at ``target_level_dbfs``.
    Positionless (additive) sources keep their TIR."""
    fs, hop = recipe.fs, recipe.label_hop
    target_rms = 10 ** (recipe.target_level_dbfs / 20)
    gains = np.zeros(len(levels))
    if recipe.sources[0].power_db is None:
        for k, s in enumerate(recipe.sources):
            gains[k] = (target_rms if k == 0 else target_rms * 10 ** (-s.tir_db / 20)) / levels[k]
        return gains
    clip = np.array([active_rms(x[None], a, fs, hop) for x, a in zip(dry, active)])
    emitted = np.array([10 ** (s.power_db / 20) / clip[k] if s.power_db is not None else np.nan
                        for k, s in enumerate(recipe.sources)])
    scale = target_rms / (levels[0] * emitted[0])
    for k, s in enumerate(recipe.sources):
        gains[k] = scale * emitted[k] if s.power_db is not None else target_rms * 10 ** (-s.tir_db / 20) / levels[k]
    return gains


def _mixed_noise(recipe: SceneRecipe, item, target: np.ndarray, level_ch) -> "MixedNoise":
    """A noise of the recipe at its level against the target's image ``target`` (the
    first receiver's, in the mix), heard by every receiver at that one gain."""
    poses = (recipe.array, *recipe.receivers)
    raw = [noise_image(item, p, recipe.fs, recipe.n_samples, recipe.duration, recipe.label_hop,
                       recipe.activity_threshold_db) for p in poses]
    g = noise_gain(item, target, raw[0], level_ch)
    if g == 0 and item.snr_db is not None:  # silence at an SNR: the record would say none was heard
        what = f"ambience {item.file} from sample {item.offset}" if item.file else f"its {item.kind} noise"
        raise AudioError(f"{recipe.scene_id}: {what} is silent in the scene; no gain puts it at {item.snr_db:g} dB: "
                         f"replace the recording (or cut its silent stretches), or set noise.{item.kind} off")
    scaled = tuple(r * np.float32(g) for r in raw)
    snr = None
    if item.snr_db is not None and g > 0:
        snr = 10 * np.log10(omni_energy(target, level_ch) / omni_energy(scaled[0], level_ch))
    return MixedNoise(item, g, scaled, snr)


def render_scene(recipe: SceneRecipe, roots: Roots | None = None) -> Scene:
    """Render one scene: its mixture, per-frame labels and record.

    Depends on nothing but the recipe and the files it names (clips, the RIR bank), so
    any worker, at any time, renders the same bytes.

    Parameters
    ----------
    recipe : SceneRecipe
    roots : Roots, optional
        Where the recipe's relative file names are on this machine (a plan's recipes
        name clips relative to the corpus); the record keeps the recipe's names.

    Returns
    -------
    Scene
        The type the reader returns (store/scene.py): ``audio`` float32 [C, T] (T = duration·fs), ``azimuth``/``elevation`` float32
        [S, F] degrees and ``distance`` [S, F] metres in the array frame (NaN for additive
        sources), ``active`` bool [S, F], ``mic_positions`` float32 [C, 3] metres, and the
        :class:`~tsel_data.store.records.SceneRecord`.

    Raises
    ------
    AudioError
        A source is silent in the part of its clip the scene uses.
    """
    files = (roots or Roots()).resolve(recipe)
    with np.errstate(over="ignore", invalid="ignore"):  # what overflows is refused before it is written (store/sanity)
        parts = mix_parts(files)
    active, gains, norm, levels, peak, mix = parts.active, parts.gains, parts.norm, parts.levels, parts.peak, parts.mix
    rt60_measured = parts.rt60_measured

    labels = [source_labels(recipe, k) for k in range(len(recipe.sources))]
    az = np.stack([l[0] for l in labels])
    el = np.stack([l[1] for l in labels])
    dist = np.stack([l[2] for l in labels])
    mics = recipe.array.mics().astype(np.float32)

    query, extra = recipe.query, {}
    qp = recipe.query_plan
    if qp is not None:
        # decided on what was rendered: image levels in the mix, activity and position labels
        truth = Truth(np.array([db(levels[k] * gains[k] * norm) for k in range(len(levels))]), active, az, el,
                      dist, recipe.label_hop)
        d = decide(qp, recipe.query, truth, recipe.scene_id)
        query = d.text
        extra = dict(query_type=str(d.type), query_relation=d.relation, query_evidence=d.evidence,
                     query_alternatives=list(d.alternatives), pairing=qp.pairing, query_wanted=qp.wanted)
    room, centre, yaw = _room_and_pose(files, rt60_measured, recipe.bank)
    if recipe.descriptors and room.dims:
        room = replace(room, volume_m3=round(float(np.prod(room.dims)), 3),
                       floor_area_m2=round(float(room.dims[0] * room.dims[1]), 3))
    record = SceneRecord(
        scene_id=recipe.scene_id, split=recipe.split, index=recipe.index, seed=recipe.seed,
        scenario=recipe.scenario, query=query, motion="moving" if recipe.moving else "static",
        rir_method=recipe.rir_method, room=room,
        array=ArrayRecord.of(recipe.array, centre, yaw, np.round(mics.astype(np.float64), 6).tolist(),
                             _hardware_record(recipe, 0)),
        sources=tuple(
            SourceRecord.of(
                s, label_list(az[k], LABEL_DECIMALS["azimuth"]), label_list(el[k], LABEL_DECIMALS["elevation"]),
                label_list(dist[k], LABEL_DECIMALS["distance"]), active[k].tolist(), round(db(gains[k] * norm), 3),
                round(db(levels[k] * gains[k] * norm), 3),
                *((None, None) if qp is None else (qp.pairings[k] or "target", qp.similarity[k])),
                **({} if not recipe.descriptors else
                   {"acoustics": parts.descriptors[k], "motion": motion_class(az[k], el[k], dist[k], active[k])}))
            for k, s in enumerate(recipe.sources)),
        levels=LevelsRecord(recipe.target_level_dbfs, round(peak * norm, 6), round(db(norm), 3)),
        receivers=tuple(ArrayRecord.of(p, centre, yaw, np.round(p.mics(), 6).tolist(), _hardware_record(recipe, k + 1))
                        for k, p in enumerate(recipe.receivers)),
        noise=tuple(_noise_record(recipe_item, nz, norm, recipe.array.spec.level_slice())
                    for recipe_item, nz in zip(recipe.noise, parts.noise)),
        **extra,
    )
    others = {p.format: (m, p.mics().astype(np.float32)) for p, (_, m) in zip(recipe.receivers, parts.others)}
    noise = {n.kind: (n.snr_db, n.level_dbfs) for n in record.noise}
    return Scene(recipe.scene_id, recipe.split, recipe.index, query, mix, az, el, dist, active, mics, recipe.fs,
                 recipe.label_hop, recipe.array.format, record, receivers=others, noise=noise)


def _hardware_record(recipe: SceneRecipe, k: int) -> HardwareRecord | None:
    """What the record says of receiver ``k``'s microphones (``recipe.hardware``), or None."""
    return HardwareRecord.of(recipe.hardware[k]) if recipe.hardware else None


def _noise_record(item, nz, norm: float, level_ch) -> NoiseRecord:
    """What the record says of one noise: as planned (``item``, names as the plan gives
    them) and as mixed (``nz``: its SNR measured, its level after the clipping guard)."""
    return NoiseRecord.of(item, None if nz.snr_db is None else round(float(nz.snr_db), 3),
                          round(noise_level_dbfs(nz.images[0] * np.float32(norm), level_ch), 3))


def _started(x: np.ndarray, start: float, fs: int) -> np.ndarray:
    """The clip as heard from ``start`` seconds into the scene: silence before, cut at the end."""
    n = int(round(start * fs))
    if n <= 0:
        return x
    out = np.zeros_like(x)
    out[n:] = x[: max(len(x) - n, 0)]
    return out


def _blame_rirs(recipe: SceneRecipe, k: int) -> None:
    """A sounding clip whose image is NaN or silent: the RIRs are at fault, not the clip."""
    s = recipe.sources[k]
    if s.bank is not None:
        b = s.bank
        raise BankError(f"{recipe.bank.path}: room {b.room} trajectory {b.trajectory}, RIRs {list(b.indices)[:6]}"
                        f"{'...' if len(b.indices) > 6 else ''}: NaN, Inf or all zero (scene {recipe.scene_id}, "
                        f"source {k}); the bank is damaged: re-import it or drop the room")
    raise BankError(f"{recipe.scene_id}: source {k}'s simulated RIRs are NaN or all but silent (room {recipe.room}); "
                    f"this is a simulator failure: report it with the scene's recipe")


def _bank(recipe: SceneRecipe):
    return open_bank_cached(recipe.bank.path, recipe.array.spec.bank_format)


def _room_and_pose(recipe: SceneRecipe, rt60_measured, named: BankRef | None) -> tuple[RoomRecord, list | None, float | None]:
    """The room record, and the array's centre and yaw in the room: the recipe's, or for
    bank scenes what the bank says (simulated banks know the pose; measured ones do not:
    None). ``recipe`` names files as they are here; the record names the bank as the
    plan does (``named``)."""
    if recipe.room is not None:
        room = RoomRecord(dims=list(recipe.room.dims), rt60=recipe.room.rt60, rt60_measured=rt60_measured)
        return room, list(recipe.array.centre), recipe.array.yaw
    info = _bank(recipe).room_info(recipe.bank.room)
    room = RoomRecord(name=recipe.bank.room, bank=named.path, dims=info.get("dims", info.get("dimensions")),
                      rt60=info.get("rt60"))
    arr = info.get("array") or {}
    if arr.get("centre") is None or arr.get("yaw") is None:
        return room, None, None
    return room, [float(v) for v in arr["centre"]], float(arr["yaw"])
