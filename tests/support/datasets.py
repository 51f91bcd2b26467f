"""Build small, physically consistent datasets with the real shard writer (tests only).

Each directional source is band-limited noise arriving as a plane wave from its
labelled direction: per-mic fractional delays ``-p·u / c`` for mic arrays (free field),
ACN/SN3D gains for FOA. Activity is a block pattern, so some frames hold exactly one
source. ``rotate`` adds degrees to the *labels* of chosen scenes (not to the audio), to
make deliberately wrong data.
"""
from __future__ import annotations

import json
import os

import numpy as np

from tsel_data.core.atomic import write_json
from tsel_data.core.geometry import SOUND_SPEED, array_to_room, foa_gains, sph_to_cart, wrap_azimuth
from tsel_data.core.jsonable import jsonable
from tsel_data.receivers import mic_positions
from tsel_data.store.dataset import dataset_doc, shard_attrs
from tsel_data.store.records import SceneRecord
from tsel_data.store.scene import Scene
from tsel_data.store.writer import write_shard


def plane_wave(sig: np.ndarray, az, el, fmt: str, mics: np.ndarray, fs: int, hop: int) -> np.ndarray:
    """Render mono ``sig`` [T] from per-frame directions ``az``/``el`` [F] -> [C, T]."""
    n = len(sig)
    spec = np.fft.rfft(sig)
    freqs = np.fft.rfftfreq(n, 1.0 / fs)
    out = np.zeros((len(mics), n))
    for f, (a, e) in enumerate(zip(np.atleast_1d(az), np.atleast_1d(el))):
        s0, s1 = f * hop, min(n, (f + 1) * hop)
        if fmt == "foa":
            out[:, s0:s1] = foa_gains(a, e)[:, None] * sig[None, s0:s1]
            continue
        u = sph_to_cart(a, e, 1.0)
        delays = -(mics @ u) / SOUND_SPEED  # seconds; a mic nearer the source hears it earlier
        shifted = np.fft.irfft(spec[None, :] * np.exp(-2j * np.pi * freqs[None, :] * delays[:, None]), n=n)
        out[:, s0:s1] = shifted[:, s0:s1]
    return out


def make_scene(split, index, *, fmt="mic4", rng, n_frames=20, fs=16000, hop_s=0.1, az=None, moving=False,
               additive=False, rotate=0.0):
    hop = int(round(hop_s * fs))
    n = n_frames * hop
    side = 0.12
    mics = mic_positions(fmt, side if fmt == "mic4" else None)
    centre, yaw = (3.0, 2.5, 1.1), float(rng.uniform(-180, 180))
    az_t = float(rng.uniform(-180, 180)) if az is None else az
    az_i = float(wrap_azimuth(az_t + rng.uniform(70, 290)))
    tgt_az = wrap_azimuth(az_t + (np.linspace(0, 60, n_frames) if moving else np.zeros(n_frames)))
    srcs_az = [tgt_az, np.full(n_frames, az_i)]
    srcs_el = [np.full(n_frames, 10.0), np.full(n_frames, -5.0)]
    srcs_d = [np.full(n_frames, 1.8), np.full(n_frames, 2.4)]
    # Target alone in the first 40 % of frames, both in the middle, interferer alone at the end.
    act = np.zeros((2 + additive, n_frames), bool)
    act[0, : int(0.7 * n_frames)] = True
    act[1, int(0.4 * n_frames):] = True
    audio = np.zeros((len(mics), n))
    for s in range(2):
        noise = rng.standard_normal(n) * np.repeat(act[s], hop)
        audio += plane_wave(noise, srcs_az[s], srcs_el[s], fmt, mics, fs, hop)
    if additive:
        act[2, int(0.8 * n_frames):] = True
        audio += 0.3 * (rng.standard_normal(n) * np.repeat(act[2], hop))[None, :]
    audio = (0.3 * audio / np.max(np.abs(audio))).astype(np.float32)

    az_arr = np.stack(srcs_az + ([np.full(n_frames, np.nan)] if additive else [])).astype(np.float32)
    el_arr = np.stack(srcs_el + ([np.full(n_frames, np.nan)] if additive else [])).astype(np.float32)
    d_arr = np.stack(srcs_d + ([np.full(n_frames, np.nan)] if additive else [])).astype(np.float32)
    if rotate:
        az_arr[:2] = wrap_azimuth(az_arr[:2] + rotate)
    scene_id = f"{split}-{index:06d}"
    sources = []
    for s in range(az_arr.shape[0]):
        directional = s < 2
        pos = array_to_room(sph_to_cart(az_arr[s, 0], el_arr[s, 0], d_arr[s, 0]), centre, yaw) if directional else None
        sources.append({
            "role": "target" if s == 0 else "interferer", "clip_id": f"clip{(index * 3 + s) % 5}",
            "audio": f"/x/clip{s}.wav", "captions": [f"caption {s} of scene {index}"],
            "spatial": "directional" if directional else "additive", "moving": bool(moving and s == 0),
            "position": None if pos is None else pos.tolist(),
            "azimuth": az_arr[s].tolist(), "elevation": el_arr[s].tolist(), "distance": d_arr[s].tolist(),
            "active": act[s].tolist(), "tir_db": None if s == 0 else float(rng.uniform(-5, 5)),
            "gain_db": 0.0, "level_dbfs": float(-25 - 3 * s),
        })
    record = {
        "scene_id": scene_id, "split": split, "index": index, "seed": int(rng.integers(1 << 30)),
        "scenario": "directional+additive" if additive else "two-directional",
        "query": f"a dog barks while {'a car' if index % 2 else 'rain'} passes number {index}",
        "motion": "moving" if moving else "static", "rir_method": "free-field",
        "room": {"dims": [6.0, 5.0, 3.0], "rt60": 0.6, "rt60_measured": 0.55},
        "array": {"format": fmt, "centre": list(centre), "yaw": yaw, "side": side if fmt == "mic4" else None,
                  "mic_positions": mics.tolist()},
        "sources": sources,
        "levels": {"target_level_dbfs": -25.0, "peak": float(np.max(np.abs(audio))), "normalisation_db": 0.0},
    }
    return Scene(scene_id=scene_id, split=split, index=index, query=record["query"], audio=audio, azimuth=az_arr,
                 elevation=el_arr, distance=d_arr, active=act, mic_positions=mics.astype(np.float32), fs=fs,
                 label_hop=hop_s, format=fmt, record=SceneRecord.from_json(record))


def make_dataset(root, *, fmt="mic4", splits=None, seed=0, n_frames=20, fs=16000, moving=(), additive=(),
                 rotate=None, shard_size=2, target_az=None):
    """Write a dataset under ``root``; returns {split: [Scene, ...]}.

    splits: {name: n_scenes}. moving / additive: scene ids with a moving target / an
    additive third source. rotate: {scene_id: degrees} added to that scene's labels.
    """
    splits = splits or {"train": 3, "test": 2}
    rotate = rotate or {}
    target_az = target_az or {}
    rng = np.random.default_rng(seed)
    out = {}
    attrs = shard_attrs(fs, 0.1, fmt)
    entries = {}
    for split, count in splits.items():
        scenes = []
        for i in range(count):
            sid = f"{split}-{i:06d}"
            scenes.append(make_scene(split, i, fmt=fmt, rng=rng, n_frames=n_frames, fs=fs, moving=sid in moving,
                                     additive=sid in additive, rotate=rotate.get(sid, 0.0),
                                     az=target_az.get(sid)))
        entries[split] = [write_shard(str(root), split, k, scenes[j: j + shard_size], attrs)
                          for k, j in enumerate(range(0, count, shard_size))]
        out[split] = scenes
    config = {"audio": {"fs": fs, "duration": n_frames * 0.1, "label_hop": 0.1},
              "splits": {s: {"count": n} for s, n in splits.items()}}
    write_json(os.path.join(root, "dataset.json"), dataset_doc(config, seed, attrs, entries))
    return out


def plan_recipes(cfg, split, view):
    """Every recipe of a split, planned in memory (what `tsel plan` writes, unserialised)."""
    from tsel_data.plan.sampler import plan_scene

    return [plan_scene(cfg, split, i, view) for i in range(cfg.splits[split].count)]


# The real AudioCaps manifests, beside the checkout when available (tests that need them skip otherwise).
SHARED_AUDIOCAPS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "shared", "audiocaps")


def assert_same_scene(a, b):
    assert a.scene_id == b.scene_id and a.query == b.query and a.index == b.index
    assert a.audio.dtype == b.audio.dtype == np.float32
    np.testing.assert_array_equal(a.audio, b.audio)  # bit for bit
    for key in ("azimuth", "elevation", "distance", "active", "mic_positions"):
        x, y = getattr(a, key), getattr(b, key)
        assert x.dtype == y.dtype and x.shape == y.shape, key
        np.testing.assert_array_equal(x, y, err_msg=key)
    assert (a.fs, a.label_hop, a.format) == (b.fs, b.label_hop, b.format)
    assert json.dumps(jsonable(a.record)) == json.dumps(jsonable(b.record))
