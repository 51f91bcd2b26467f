"""What a scene hears besides its sources (``[noise]``, recipe ``noise``): each
:class:`~tsel_data.scene.recipe.NoiseItem` as a receiver hears it, and its level.

- ``ambience``: the recording's stretch named by the recipe (tsel_data/corpus/ambience.py), as
  recorded: it must have the receiver's channels.
- ``diffuse``: stationary Gaussian noise with the receiver's diffuse-field cross-spectra
  (its capsule model's ``diffuse_csd``, acoustics/capsules.py) shaped by a spectrum:
  white, pink (1/f), brown (1/f²) above 20 Hz, or a corpus clip's long-term spectrum.
- ``babble``: corpus clips, each at an equal active level, each a plane wave from its own
  direction (a far source of the free field: its capsule model with one image 10 m away).
- ``sensor``: independent white noise on every channel.

Levels (:func:`noise_gain`): an SNR is against the target's omni energy over the whole
scene, as the DCASE generator defines it (ambience.snr_gain: the energy of the mean over
the receiver's level channels), measured on the first receiver; sensor noise at a level
in dBFS is that RMS per channel. Noise is never a source: no label, no position.
"""
from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..acoustics.capsules import capsule_model
from ..acoustics.late import csd_noise
from ..core.geometry import SOUND_SPEED, array_to_room, sph_to_cart
from ..corpus.ambience import omni_energy, read_segment, snr_gain
from ..corpus.audio import active_rms, frame_activity, load_clip_cached
from ..dsp import realfft as sfft  # scipy.fft's numbers without its import
from ..dsp.timevarying import render_static
from ..choices import NoiseKind, NoiseSpectrum, SensorLevel
from ..errors import AudioError, ConfigError
from ..scene.recipe import NoiseItem

BABBLE_DISTANCE = 10.0  # m: a far source, a plane wave to a 10 cm array (its curvature is below 0.5 mm)
SPECTRUM_FLOOR = 20.0  # Hz: pink and brown spectra are flat below it (no infinite DC)
# power falls as 1/f^k above the floor
SPECTRUM_EXPONENTS = {NoiseSpectrum.WHITE: 0.0, NoiseSpectrum.PINK: 1.0, NoiseSpectrum.BROWN: 2.0}


# --- drawing (the planner: a recipe's NoiseItem, from the scene's noise stream) ------------------


def _draw_ambience(cfg, rng, index: int, cat, chosen, bank_room, n: int) -> NoiseItem:
    nc = cfg.noise
    rec = cat.ambience.for_room(bank_room, rng)
    offset = rec.offset(rng, n, nc.ambience_segments, index)
    rel = os.path.relpath(rec.path, cat.ambience.root).replace(os.sep, "/")
    return NoiseItem(NoiseKind.AMBIENCE, int(rng.integers(2**31 - 1)), round(float(nc.ambience_snr.sample(rng)), 3),
                     file=rel, offset=offset)


def _draw_diffuse(cfg, rng, index: int, cat, chosen, bank_room, n: int) -> NoiseItem:
    nc = cfg.noise
    clips = ()
    if nc.diffuse == NoiseSpectrum.CLIP:
        c = cat.clips[cat.draw(rng)]
        clips = ((cat.roots.relative_clip(c.audio), c.offset),)
    return NoiseItem(NoiseKind.DIFFUSE, int(rng.integers(2**31 - 1)), round(float(nc.diffuse_snr.sample(rng)), 3),
                     spectrum=str(nc.diffuse), clips=clips)


def _draw_babble(cfg, rng, index: int, cat, chosen, bank_room, n: int) -> NoiseItem:
    nc = cfg.noise
    pool = np.setdiff1d(np.arange(len(cat.clips)), chosen)
    while True:  # clips a full check found bad (cat.excluded) are drawn again, the others kept as drawn
        if len(pool) < nc.babble:  # never fewer talkers than asked, silently
            raise ConfigError(f"noise.babble = {nc.babble} asks for {nc.babble} babble clips besides a scene's "
                              f"{len(chosen)} sources, but the split has {len(cat.clips)} usable clips; lower "
                              f"noise.babble to at most {len(pool)}")
        picked = rng.choice(pool, size=nc.babble, replace=False)
        bad = [int(i) for i in picked if int(i) in cat.excluded]
        if not bad:
            break
        pool = np.setdiff1d(pool, bad)
    clips = tuple((cat.roots.relative_clip(cat.clips[i].audio), cat.clips[i].offset) for i in picked)
    az = rng.uniform(-180.0, 180.0, len(picked))
    el = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, len(picked))))  # uniform over the sphere
    dirs = tuple((round(float(a), 3), round(float(e), 3)) for a, e in zip(az, el))
    return NoiseItem(NoiseKind.BABBLE, int(rng.integers(2**31 - 1)), round(float(nc.babble_snr.sample(rng)), 3),
                     clips=clips, directions=dirs)


def _draw_sensor(cfg, rng, index: int, cat, chosen, bank_room, n: int) -> NoiseItem:
    nc = cfg.noise
    level = round(float(nc.sensor_level.sample(rng)), 3)
    seed = int(rng.integers(2**31 - 1))
    return (NoiseItem(NoiseKind.SENSOR, seed, level, None) if nc.sensor == SensorLevel.SNR
            else NoiseItem(NoiseKind.SENSOR, seed, None, level))


# --- images (the renderer: an item as a receiver hears it, unscaled) -----------------------------


def _ambience_image(item, pose, fs: int, n: int, duration: float, hop: float, threshold_db: float) -> np.ndarray:
    x = read_segment(item.file, int(item.offset), n)
    if x.shape[0] != pose.n_channels:
        raise AudioError(f"ambience {item.file} has {x.shape[0]} channels but {pose.format} has {pose.n_channels}; "
                         f"use recordings made with the receiver (TAU-SNoise_DB: foa or tetra)")
    return x


def _sensor_image(item, pose, fs: int, n: int, duration: float, hop: float, threshold_db: float) -> np.ndarray:
    return np.random.default_rng([item.seed, 0]).standard_normal((pose.n_channels, n)).astype(np.float32)


def _diffuse_image(item, pose, fs: int, n: int, duration: float, hop: float, threshold_db: float) -> np.ndarray:
    rng = np.random.default_rng([item.seed, 0])
    model = capsule_model(pose, fs)
    shape = _spectrum(item, fs, duration)
    return csd_noise(rng, 1, n, fs, lambda f: model.diffuse_csd(f) * shape(f)[:, None, None])[0].astype(np.float32)


def _babble_image(item, pose, fs: int, n: int, duration: float, hop: float, threshold_db: float) -> np.ndarray:
    model = capsule_model(pose, fs)
    out = np.zeros((pose.n_channels, n), dtype=np.float32)
    for (path, offset), (az, el) in zip(item.clips, item.directions):
        x = load_clip_cached(path, fs, duration, float(offset))
        level = active_rms(x[None], frame_activity(x, fs, hop, int(round(duration / hop)), threshold_db), fs, hop)
        if not level > 0:
            continue  # a silent clip adds nothing
        out += render_static(x / level, _plane_wave(model, pose, az, el, fs))[:, :n]
    return out


@dataclass(frozen=True)
class NoiseSpec:
    """One kind of noise: whether a config asks for it (``enabled(noise_config)``), how the
    planner draws its :class:`~tsel_data.scene.recipe.NoiseItem` (``draw(cfg, rng, index,
    catalog view, chosen clips, bank room, samples)``), and how a receiver hears it
    (``image(item, pose, fs, samples, duration, hop, threshold_db)``, unscaled)."""

    enabled: Callable
    draw: Callable
    image: Callable


# One entry per kind, in the order the planner draws them from a scene's noise stream:
# adding a kind is its enum value (choices.NoiseKind), its spec here and its config keys.
NOISE_KINDS = {
    NoiseKind.AMBIENCE: NoiseSpec(lambda nc: bool(nc.ambience), _draw_ambience, _ambience_image),
    NoiseKind.DIFFUSE: NoiseSpec(lambda nc: nc.diffuse != NoiseSpectrum.NONE, _draw_diffuse, _diffuse_image),
    NoiseKind.BABBLE: NoiseSpec(lambda nc: bool(nc.babble), _draw_babble, _babble_image),
    NoiseKind.SENSOR: NoiseSpec(lambda nc: nc.sensor != SensorLevel.NONE, _draw_sensor, _sensor_image),
}


def draw_noise(cfg, rng, index: int, cat, chosen, bank_room) -> tuple:
    """A scene's noises: every kind its config asks for, drawn in :data:`NOISE_KINDS` order."""
    n = int(round(cfg.audio.duration * cfg.audio.fs))
    return tuple(spec.draw(cfg, rng, index, cat, chosen, bank_room, n)
                 for spec in NOISE_KINDS.values() if spec.enabled(cfg.noise))


def noise_image(item, pose, fs: int, n: int, duration: float, hop: float, threshold_db: float) -> np.ndarray:
    """NoiseItem ``item`` as ``pose`` hears it, unscaled: float32 [C, n]."""
    try:
        spec = NOISE_KINDS[item.kind]
    except KeyError:
        raise ValueError(f"unknown noise kind {item.kind!r}") from None
    return spec.image(item, pose, fs, n, duration, hop, threshold_db)


def noise_gain(item, target_image: np.ndarray, noise: np.ndarray, level_channels) -> float:
    """The gain that puts ``noise`` (the first receiver's) at ``item``'s SNR against
    ``target_image`` (the target's image in the mix, same receiver), or for sensor noise
    at ``level_dbfs`` RMS per channel."""
    if item.snr_db is None:
        rms = float(np.sqrt(np.mean(np.asarray(noise, dtype=np.float64) ** 2)))
        return 10 ** (item.level_dbfs / 20) / rms if rms > 0 else 0.0
    if omni_energy(noise, level_channels) <= 0:
        return 0.0
    return snr_gain(target_image, noise, item.snr_db, level_channels)


def _spectrum(item, fs: int, duration: float):
    """freqs -> the diffuse noise's power spectrum (1 at its reference)."""
    if item.spectrum == NoiseSpectrum.CLIP:
        path, offset = item.clips[0]
        x = np.asarray(load_clip_cached(path, fs, duration, float(offset)), dtype=np.float64)
        n_fft = 4096
        frames = x[: len(x) // n_fft * n_fft].reshape(-1, n_fft) * np.hanning(n_fft)
        psd = np.mean(np.abs(sfft.rfft(frames, axis=-1)) ** 2, axis=0) if len(frames) else np.ones(n_fft // 2 + 1)
        psd = psd / max(float(psd.mean()), 1e-30)
        grid = sfft.rfftfreq(n_fft, 1.0 / fs)
        return lambda f: np.interp(f, grid, psd)
    power = SPECTRUM_EXPONENTS[item.spectrum]
    return lambda f: (np.maximum(np.asarray(f, dtype=np.float64), SPECTRUM_FLOOR) / 1000.0) ** -power


def _plane_wave(model, pose, az: float, el: float, fs: int) -> np.ndarray:
    """The receiver's response [C, L] to a far source at (az, el) of the array frame, unit
    amplitude at the centre (free field: one image, no walls)."""
    pos = array_to_room(sph_to_cart(az, el, BABBLE_DISTANCE), pose.centre, pose.yaw)[None, :]
    n = int(np.ceil((BABBLE_DISTANCE + 0.5) / SOUND_SPEED * fs)) + 64
    grid = model.new_grid(n)
    model.add(grid, pos, np.array([4 * np.pi * BABBLE_DISTANCE]), None)
    return model.render(grid).astype(np.float32)


def noise_level_dbfs(noise: np.ndarray, level_channels) -> float:
    """A scaled noise's level as the record states it: the RMS of its level channels, dBFS."""
    x = np.asarray(noise, dtype=np.float64)[level_channels]
    rms = float(np.sqrt(np.mean(x ** 2))) if x.size else 0.0
    return 20 * np.log10(rms) if rms > 0 else float("-inf")

