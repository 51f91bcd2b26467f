"""Check labels against the audio with a classical localizer.

Per label frame we compute an azimuth map (360 one-degree bins, array frame):

- **mic arrays** (mic4, tetra): SRP-PHAT (DiBiase, 2000), the sum over all mic pairs
  of the GCC-PHAT at the pair's far-field delay ``τ_ij(u) = -(p_i - p_j)·u / c`` for a
  grid of directions u (1° azimuth × a few elevations, maximum over elevation). The
  mic positions come from the scene (``mic_positions``).
- **FOA**: the active acoustic intensity vector (Merimaa & Pulkki; Ahonen et al.)
  ``I(t, f) = Re{W*(t, f) · [X, Y, Z](t, f)}`` per time-frequency bin; its azimuth
  ``atan2(I_y, I_x)`` is histogrammed with weight ``|I_xy|`` and smoothed.

A source is *tested* on the frames where it is active and every other source
(including additive ones) is silent, i.e. where it dominates. A static source's maps
over those frames are summed and the peak is its estimate; a moving source is checked
in windows of ``window`` frames against the circular mean of its labels there. The
source agrees when the median error is within ``tolerance``. When no source of a scene
has enough dominant frames and all are static, the scene is checked in *overlap* mode:
the summed map's K strongest peaks (K directional sources) must each explain one label.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .features import mic_pairs, stft
from .geometry import SOUND_SPEED, azimuth_difference, circular_mean, sph_to_cart, wrap_azimuth
from .progress import bar
from .store.reader import list_splits, open_dataset

_EPS = 1e-12


def doa_maps(audio, fs: int, label_hop: float, n_frames: int, fmt: str, mic_positions=None,
             n_fft: int = 1024, fmin: float = 200.0, fmax: float = 8000.0, dynamic_db: float = 20.0) -> np.ndarray:
    """Azimuth maps per label frame: audio [C, T] -> float64 [n_frames, 360] (bin k = k degrees).

    Higher means more evidence for a source there. STFT frames (hop n_fft/2) are
    assigned to the label frame that contains their centre. Only time-frequency bins
    within ``dynamic_db`` of their STFT frame's loudest bin count: PHAT weighs every
    bin alike, so without this the bins a narrow-band source leaves empty would be
    won by whatever faint residue (another source's tail, an additive bed) fills them.
    """
    hop = n_fft // 2
    spec = stft(audio, n_fft, hop, center=False)  # [C, J, K]
    centres = np.arange(spec.shape[1]) * hop + n_fft / 2
    owner = np.floor(centres / (label_hop * fs)).astype(int)
    keep = owner < n_frames
    spec, owner = spec[:, keep], owner[keep]
    freqs = np.fft.rfftfreq(n_fft, 1.0 / fs)
    band = (freqs >= fmin) & (freqs <= min(fmax, fs / 2))
    spec = spec[:, :, band]
    power = np.mean(np.abs(spec) ** 2, axis=0)  # [J, K]
    mask = power >= power.max(axis=1, keepdims=True) * 10 ** (-dynamic_db / 10)
    mask &= power > 0
    if fmt == "foa":
        return _intensity_maps(spec, mask, owner, n_frames)
    return _srp_maps(spec, mask, owner, n_frames, band, n_fft, np.asarray(mic_positions, dtype=np.float64), fs)


def _per_label_frame(x: np.ndarray, owner: np.ndarray, n_frames: int) -> np.ndarray:
    """Sum rows of x [J, ...] into label frames [n_frames, ...] (owner sorted ascending)."""
    out = np.zeros((n_frames,) + x.shape[1:], dtype=x.dtype)
    if len(owner):
        starts = np.flatnonzero(np.r_[True, np.diff(owner) > 0])
        out[owner[starts]] = np.add.reduceat(x, starts, axis=0)
    return out


def _srp_maps(spec, mask, owner, n_frames, band, n_fft, mics, fs, up: int = 4) -> np.ndarray:
    pairs = np.array(mic_pairs(spec.shape[0]))
    cross = spec[pairs[:, 0]] * np.conj(spec[pairs[:, 1]])  # [P, J, K in band]
    cross = np.where(mask, cross / (np.abs(cross) + _EPS), 0.0)
    summed = np.zeros((n_frames, len(pairs), len(band)), dtype=np.complex128)
    summed[:, :, band] = _per_label_frame(cross.transpose(1, 0, 2), owner, n_frames)
    n = n_fft * up  # zero-padded inverse FFT: GCC interpolated to 1/up sample
    gcc = np.fft.irfft(summed, n=n, axis=-1)  # [F, P, n]; lag τ at index τ·fs·up mod n
    # A planar array cannot tell up from down: search the upper half only.
    planar = np.ptp(mics[:, 2]) < 1e-6
    els = np.arange(0.0, 61.0, 15.0) if planar else np.arange(-60.0, 61.0, 15.0)
    u = sph_to_cart(np.arange(360.0)[None, :], els[:, None], 1.0)  # [E, 360, 3]
    dp = mics[pairs[:, 0]] - mics[pairs[:, 1]]  # [P, 3]
    tau = -np.einsum("pc,eac->pea", dp, u) / SOUND_SPEED  # [P, E, 360] seconds
    idx = np.rint(tau * fs * up).astype(int) % n
    maps = np.zeros((n_frames, len(els), 360))
    for p in range(len(pairs)):
        maps += gcc[:, p, idx[p]]
    return maps.max(axis=1)


def _intensity_maps(spec, mask, owner, n_frames, smooth_deg: float = 4.0) -> np.ndarray:
    w, y, x = spec[0], spec[1], spec[3]  # ACN order W, Y, Z, X
    ix, iy = np.real(np.conj(w) * x), np.real(np.conj(w) * y)  # [J, K]
    az = np.degrees(np.arctan2(iy, ix))
    weight = np.hypot(ix, iy) * mask
    bins = np.floor(az + 0.5).astype(int) % 360
    n_j = spec.shape[1]
    flat = (np.arange(n_j)[:, None] * 360 + bins).ravel()
    hist = np.bincount(flat, weights=weight.ravel(), minlength=n_j * 360).reshape(n_j, 360)
    return _smooth_circular(_per_label_frame(hist, owner, n_frames), smooth_deg)


def _smooth_circular(hist: np.ndarray, smooth_deg: float) -> np.ndarray:
    """Circular Gaussian smoothing of 1° azimuth histograms [..., 360], so near-identical
    directions pool into one peak."""
    d = np.minimum(np.arange(360), 360 - np.arange(360))
    kern = np.exp(-0.5 * (d / smooth_deg) ** 2)
    return np.real(np.fft.ifft(np.fft.fft(hist, axis=-1) * np.fft.fft(kern), axis=-1))


def vote_histogram(maps: np.ndarray, smooth_deg: float = 3.0) -> np.ndarray:
    """One vote per label frame at its map's peak -> circularly smoothed histogram [360].

    Voting (rather than summing maps) keeps a few frames with very coherent residue,
    e.g. a steady hum of a source labelled inactive, from outweighing the majority.
    """
    votes = np.argmax(maps, axis=1)[np.ptp(maps, axis=1) > 0]
    return _smooth_circular(np.bincount(votes, minlength=360).astype(np.float64), smooth_deg)


def _peaks(m: np.ndarray, k: int, min_sep: float) -> list[int]:
    """Up to k azimuth bins of the highest local maxima at least ``min_sep`` apart."""
    order = np.argsort(m)[::-1]
    chosen: list[int] = []
    for b in order:
        if all(azimuth_difference(b, c) >= min_sep for c in chosen):
            chosen.append(int(b))
            if len(chosen) == k:
                break
    return chosen


def verify_scene(scene, tolerance: float = 20.0, min_frames: int = 3, window: int = 5, **map_kw) -> dict:
    """Check one scene (with audio). Returns {scene_id, status, mode, sources: [...]}.

    status: ``agree`` | ``disagree`` | ``untested`` (no frame on which a check can run).
    """
    maps = doa_maps(scene.audio, scene.fs, scene.label_hop, scene.n_frames, scene.format, scene.mic_positions, **map_kw)
    az_all = scene.azimuth.astype(np.float64)
    directional = [s for s in range(scene.n_sources) if np.isfinite(az_all[s]).any()]
    roles = [src.role for src in scene.record.sources]
    active = scene.active.astype(bool)
    results = []
    for s in directional:
        others = np.delete(active, s, axis=0).any(axis=0) if scene.n_sources > 1 else np.zeros_like(active[s])
        dom = np.flatnonzero(active[s] & ~others & np.isfinite(az_all[s]))
        if len(dom) < min_frames:
            continue
        static = float(np.max(azimuth_difference(az_all[s][dom], az_all[s][dom][0]))) < 1.0
        groups = [dom] if static else [g for g in np.split(dom, np.flatnonzero(np.diff(dom // window)) + 1) if len(g)]
        errs, ests, truths = [], [], []
        for g in groups:
            est = float(np.argmax(vote_histogram(maps[g])))
            truth = circular_mean(az_all[s][g])
            errs.append(float(azimuth_difference(est, truth)))
            ests.append(float(wrap_azimuth(est)))
            truths.append(truth)
        i = int(np.argsort(errs)[len(errs) // 2])  # the median window: its label and estimate explain the error
        results.append({"source": s, "role": roles[s] if s < len(roles) else "", "frames": int(len(dom)),
                        "windows": len(groups), "label": truths[i], "estimate": ests[i], "error": errs[i],
                        "agree": errs[i] <= tolerance})
    mode = "single"
    if not results and directional:
        # Additive sources are the same signal on every channel: their zero-lag peak would
        # pose as a direction, so overlap mode uses only the frames where they are silent.
        positionless = [s for s in range(scene.n_sources) if s not in directional]
        quiet = ~active[positionless].any(axis=0) if positionless else np.ones(scene.n_frames, bool)
        frames = np.flatnonzero(active[directional].any(axis=0) & quiet)
        static_all = all(float(np.nanmax(azimuth_difference(az_all[s], az_all[s][np.isfinite(az_all[s])][0]))) < 1.0
                         for s in directional)
        if len(frames) >= min_frames and static_all:
            mode = "overlap"
            m = vote_histogram(maps[frames])
            peaks = _peaks(m, len(directional), min_sep=2 * tolerance)
            for s in directional:
                truth = circular_mean(az_all[s][np.isfinite(az_all[s])])
                errs = [float(azimuth_difference(p, truth)) for p in peaks]
                j = int(np.argmin(errs))
                results.append({"source": s, "role": roles[s] if s < len(roles) else "", "frames": int(len(frames)),
                                "label": truth, "estimate": float(wrap_azimuth(peaks[j])), "error": errs[j],
                                "agree": errs[j] <= tolerance})
    if not results:
        return {"scene_id": scene.scene_id, "status": "untested", "mode": None, "sources": []}
    status = "agree" if all(r["agree"] for r in results) else "disagree"
    return {"scene_id": scene.scene_id, "status": status, "mode": mode, "sources": results}


@dataclass
class VerifyReport:
    """Per split: scenes checked, agreement rate, and the disagreeing scenes."""

    tolerance: float
    splits: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"tolerance": self.tolerance, "splits": self.splits}

    def format_text(self, max_list: int = 20) -> str:
        lines = [f"label check with a classical localizer (tolerance {self.tolerance:g} deg)",
                 f"{'split':<10}{'scenes':>8}{'tested':>8}{'agree':>8}{'rate':>9}{'median err':>12}"]
        for name, v in self.splits.items():
            rate = f"{100 * v['rate']:.1f}%" if v["tested"] else "-"
            med = f"{v['median_error']:.1f}" if v["tested"] else "-"
            lines.append(f"{name:<10}{v['scenes']:>8}{v['tested']:>8}{v['agree']:>8}{rate:>9}{med:>12}")
        untested = sum(len(v["untested"]) for v in self.splits.values())
        if untested:
            lines.append(f"{untested} scene(s) untested: no frames where one source plays alone, nor frames "
                         f"free of additive sources")
        bad = [(n, d) for n, v in self.splits.items() for d in v["disagree"]]
        if bad:
            lines.append(f"{len(bad)} scene(s) disagree:")
            for name, d in bad[:max_list]:
                worst = max(d["sources"], key=lambda r: r["error"])
                n = worst.get("windows", 1)
                where = f"in the median of {n} windows, " if n > 1 else ""
                lines.append(f"  {d['scene_id']}: source {worst['source']} ({worst['role']}) {where}labelled "
                             f"{worst['label']:.1f} deg, audio says {worst['estimate']:.1f} deg "
                             f"(error {worst['error']:.1f}, {d['mode']} mode)")
            if len(bad) > max_list:
                lines.append(f"  ... and {len(bad) - max_list} more (use --json for all)")
        else:
            lines.append("no scene disagrees")
        return "\n".join(lines)


def verify_dataset(root: str, splits=None, tolerance: float = 20.0, min_frames: int = 3,
                   max_scenes: int | None = None, progress: bool | None = False) -> VerifyReport:
    """Run :func:`verify_scene` on every scene (or the first ``max_scenes``) of each split.

    ``progress``: a bar per split (None: when stderr is a terminal). A dataset still
    being made is verified on its finished shards.
    """
    report = VerifyReport(tolerance)
    for split in (list(splits) if splits else list_splits(root, unfinished=True)):
        with open_dataset(root, split, unfinished=True) as ds:
            n = len(ds) if max_scenes is None else min(len(ds), max_scenes)
            res = []
            with bar(n, f"verify {split}", "scene", progress) as b:
                for i in range(n):
                    res.append(verify_scene(ds[i], tolerance, min_frames))
                    b.update()
        tested = [r for r in res if r["status"] != "untested"]
        errors = [src["error"] for r in tested for src in r["sources"]]
        agree = sum(r["status"] == "agree" for r in tested)
        report.splits[split] = {
            "scenes": n, "tested": len(tested), "agree": agree,
            "rate": agree / len(tested) if tested else float("nan"),
            "median_error": float(np.median(errors)) if errors else float("nan"),
            "untested": [r["scene_id"] for r in res if r["status"] == "untested"],
            "disagree": [r for r in res if r["status"] == "disagree"],
        }
    return report
