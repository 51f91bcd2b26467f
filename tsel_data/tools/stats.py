"""Dataset statistics per split, from the labels and JSON records (no audio is read).

Per split: scene count, scenarios, moving fraction, clip use and reuse, a 10° histogram
of target azimuths (one value per scene: the circular mean over its active frames),
angular separation between the target and the nearest other directional source,
source distances, room sizes, RT60 requested and measured, levels (target level, TIR,
peak), the target's active share of frames and mean elevation, what moves and how fast
(the median great-circle speed of each moving source along its labels), query length in
words, and the mix of query types, relations and pairings (:class:`QueryMix`), and how
many target clips are recorded below the scenes' rate (the only file read: their headers,
when the corpus is where the plan says). A dataset still being made gives the statistics
of its finished shards.
"""
from __future__ import annotations

import os
from collections import Counter

import numpy as np

from ..core.atomic import atomic_output
from ..core.geometry import azimuth_difference, circular_mean
from ..core.report import band_limited_text
from ..errors import DatasetError, TselError
from ..core.files import is_regular
from ..store.layout import Layout
from ..store.dataset import load_dataset_doc
from ..store.plans import local_roots, read_plan_doc
from ..store.reader import list_splits, open_dataset
from .evaluate import scene_snr

AZ_BIN = 10
# what moves in a scene, by (target moves) + 2 * (an interferer moves)
MOTION_KINDS = ("static", "target", "interferer", "both")


def _summ(values) -> dict:
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=np.float64)
    if not v.size:
        return {"n": 0}
    return {"n": int(v.size), "min": float(v.min()), "mean": float(v.mean()), "median": float(np.median(v)),
            "max": float(v.max())}


def _mean_az(az, active) -> float | None:
    ok = np.isfinite(az)
    if not ok.any():
        return None
    use = ok & active if (ok & active).any() else ok
    return circular_mean(az[use])


def split_stats(root: str, split: str) -> dict:
    """Statistics of one split (a JSON-friendly dict; ``raw`` holds per-scene values for plots)."""
    tally = SplitTally(root, split)
    with open_dataset(root, split, unfinished=True) as ds:
        for sc in ds.iter_labels():  # labels only: small
            tally.add(sc)
    return tally.result()


class SplitTally:
    """:func:`split_stats` scene by scene, for a caller that reads the scenes anyway (an
    export writing its card): :meth:`add` each scene of the split (labels and record;
    the audio is not looked at), then :meth:`result`. Holds per-scene numbers, not scenes."""

    def __init__(self, root: str, split: str):
        self.root, self.split, self.n, self.moving = root, split, 0, 0
        self.raw = {k: [] for k in ("target_az", "target_el", "separation", "target_dist", "interferer_dist",
                                    "room_x", "room_y", "room_z", "volume", "rt60", "rt60_measured",
                                    "target_level", "tir", "peak", "target_active", "query_words", "speed",
                                    "moves", "snr", "drr", "c50", "t30")}
        self.source_motion = Counter()  # motion classes of the directional sources (output.descriptors)
        self.clip_uses, self.target_clips = Counter(), Counter()
        self.target_audio: dict[str, str] = {}
        self.scenarios, self.motions = Counter(), Counter()
        self.queries = QueryMix()
        self.target_classes = Counter()  # recorded scenes: the class the labels name

    def add(self, sc) -> None:
        raw, rec = self.raw, sc.record
        self.n += 1
        self.queries.add(rec)
        self.scenarios[rec.scenario] += 1
        self.motions[rec.motion] += 1
        self.moving += any(s.moving for s in rec.sources) or rec.motion == "moving"
        if rec.recording is not None and rec.recording.classes:
            self.target_classes[rec.recording.classes[0]] += 1
        for k, s in enumerate(rec.sources):
            if s.clip_id is not None:
                self.clip_uses[s.clip_id] += 1
                if k == 0:
                    self.target_clips[s.clip_id] += 1
                    if s.audio:
                        self.target_audio[s.clip_id] = s.audio
            if k > 0 and s.tir_db is not None:
                raw["tir"].append(s.tir_db)
            elif k > 0 and s.power_db is not None and s.level_dbfs is not None:  # levels that follow distance: as heard
                raw["tir"].append(rec.sources[0].level_dbfs - s.level_dbfs)
        act = sc.active.astype(bool)
        t_az = _mean_az(sc.azimuth[0], act[0])
        raw["target_az"].append(t_az)
        el0 = sc.elevation[0][np.isfinite(sc.elevation[0])]
        raw["target_el"].append(float(np.mean(el0)) if el0.size else None)
        moves = [k for k, src in enumerate(rec.sources) if src.moving]
        raw["moves"].append(MOTION_KINDS[(0 in moves) + 2 * any(k > 0 for k in moves)])
        raw["speed"] += [angular_speed(sc.azimuth[k], sc.elevation[k], sc.label_hop) for k in moves]
        others = [_mean_az(sc.azimuth[s], act[s]) for s in range(1, sc.n_sources)]
        others = [a for a in others if a is not None]
        if t_az is not None and others:
            raw["separation"].append(float(min(azimuth_difference(t_az, a) for a in others)))
        raw["target_dist"].append(float(np.nanmean(sc.distance[0])) if np.isfinite(sc.distance[0]).any() else None)
        for s in range(1, sc.n_sources):
            if np.isfinite(sc.distance[s]).any():
                raw["interferer_dist"].append(float(np.nanmean(sc.distance[s])))
        room = rec.room
        if room.dims:
            x, y, z = room.dims
            raw["room_x"].append(x)
            raw["room_y"].append(y)
            raw["room_z"].append(z)
            raw["volume"].append(x * y * z)
        raw["rt60"].append(room.rt60)
        raw["rt60_measured"].append(room.rt60_measured)
        raw["target_level"].append(rec.levels.target_level_dbfs)
        raw["peak"].append(rec.levels.peak)
        raw["target_active"].append(float(act[0].mean()))
        raw["query_words"].append(len(sc.query.split()))
        if rec.noise:
            raw["snr"].append(scene_snr(rec.noise))
        target = rec.sources[0].acoustics
        if target:
            for key, name in (("drr_db", "drr"), ("c50_db", "c50"), ("t30_s", "t30")):
                raw[name].append(target.get(key))
        self.source_motion.update(src.motion for src in rec.sources if src.motion)

    def result(self) -> dict:
        raw, n, clip_uses, target_clips = self.raw, self.n, self.clip_uses, self.target_clips
        az = np.asarray([a for a in raw["target_az"] if a is not None])
        hist, _ = np.histogram(az, bins=np.arange(-180, 181, AZ_BIN))
        pairs = [(r, m) for r, m in zip(raw["rt60"], raw["rt60_measured"]) if r is not None and m is not None]
        return {
            "split": self.split,
            "scenes": n,
            "scenarios": dict(self.scenarios),
            "motion": dict(self.motions),
            "moving_fraction": self.moving / n if n else float("nan"),
            "clips": {"used": len(clip_uses), "uses": int(sum(clip_uses.values())),
                      "reused": sum(1 for c in clip_uses.values() if c > 1),
                      "max_uses": max(clip_uses.values(), default=0),
                      "target_clips": len(target_clips),
                      "target_reused": sum(1 for c in target_clips.values() if c > 1),
                      "target_band_limited": band_limited_targets(self.root, self.target_audio)},
            "target_azimuth_hist": {"bin_deg": AZ_BIN, "edges_from": -180, "counts": hist.tolist()},
            "separation_deg": _summ(raw["separation"]),
            "target_distance_m": _summ(raw["target_dist"]),
            "interferer_distance_m": _summ(raw["interferer_dist"]),
            "room_m": {"x": _summ(raw["room_x"]), "y": _summ(raw["room_y"]), "z": _summ(raw["room_z"]),
                       "volume_m3": _summ(raw["volume"])},
            "rt60_s": {"requested": _summ(raw["rt60"]), "measured": _summ(raw["rt60_measured"]),
                       "measured_minus_requested": _summ([m - r for r, m in pairs])},
            "levels_db": {"target_dbfs": _summ(raw["target_level"]), "tir": _summ(raw["tir"]),
                          "peak_dbfs": _summ([20 * np.log10(p) for p in raw["peak"] if p]),
                          "snr": _summ([v for v in raw["snr"] if v is not None])},
            "target_active_fraction": _summ(raw["target_active"]),
            "query_words": _summ(raw["query_words"]),
            "moving_sources": {"scenes": dict(Counter(raw["moves"])), "speed_deg_s": _summ(raw["speed"])},
            "target_elevation_deg": _summ(raw["target_el"]),
            "queries": self.queries.result(),
            **self._recorded(),
            **self._descriptors(),
            "raw": raw,
        }

    def _descriptors(self) -> dict:
        """{"descriptors": the targets' DRR, C50 and T30, every source's motion class} of a
        split made with output.descriptors; else {} (other stats keep their keys)."""
        if not self.source_motion and not self.raw["drr"]:
            return {}
        raw = self.raw
        return {"descriptors": {"target_drr_db": _summ(raw["drr"]), "target_c50_db": _summ(raw["c50"]),
                                "target_t30_s": _summ(raw["t30"]),
                                "source_motion": dict(self.source_motion.most_common())}}

    def _recorded(self) -> dict:
        """{"recorded": ...} of a recorded dataset's split: what its windows held, what
        was kept, skipped and why (dataset.json), and the target classes; else {}."""
        if not self.target_classes:
            return {}
        try:
            planned = (load_dataset_doc(self.root).raw.get("recorded") or {}).get(self.split) or {}
        except DatasetError:
            planned = {}
        return {"recorded": {**planned, "target_classes": dict(self.target_classes.most_common())}}


def angular_speed(az, el, hop: float) -> float | None:
    """Median angular speed (deg/s) of a source along its labels: the great-circle angle
    between consecutive frames' directions over the hop (the speed ``scene.speed`` sets)."""
    az, el = np.radians(np.asarray(az, dtype=np.float64)), np.radians(np.asarray(el, dtype=np.float64))
    u = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)
    ok = np.all(np.isfinite(u), axis=1)
    steps = np.einsum("ij,ij->i", u[:-1], u[1:])[ok[:-1] & ok[1:]]
    if not steps.size:
        return None
    return float(np.degrees(np.median(np.arccos(np.clip(steps, -1.0, 1.0)))) / hop)


class QueryMix:
    """Counts of query types, relations (``type:relation``), pairings, and of scenes whose
    query fell back from the type drawn (``wanted->got``; docs/queries.md), record by
    record (:meth:`add`, then :meth:`result`)."""

    def __init__(self):
        self.types, self.relations, self.pairings, self.fallbacks = Counter(), Counter(), Counter(), Counter()

    def add(self, rec) -> None:
        self.types[rec.query_type] += 1
        self.pairings[rec.pairing] += 1
        if rec.query_relation:
            self.relations[f"{rec.query_type}:{rec.query_relation}"] += 1
        if rec.query_wanted and rec.query_wanted != rec.query_type:
            self.fallbacks[f"{rec.query_wanted}->{rec.query_type}"] += 1

    def result(self) -> dict:
        return {"types": dict(self.types), "relations": dict(sorted(self.relations.items())),
                "pairing": dict(self.pairings), "fallbacks": dict(sorted(self.fallbacks.items()))}


def _query_lines(q: dict) -> list[str]:
    def counts(d):
        return ", ".join(f"{k} {v}" for k, v in sorted(d.items())) or "none"

    lines = [f"  queries: {counts(q['types'])}   pairing: {counts(q['pairing'])}"]
    if q["relations"]:
        lines.append(f"  relations: {counts(q['relations'])}")
    if q["fallbacks"]:
        lines.append(f"  fell back (drawn->used): {counts(q['fallbacks'])}")
    return lines


def band_limited_targets(root: str, audio: dict[str, str]) -> dict | None:
    """Of the target clips (``{clip_id: path in the corpus}``), those recorded below the
    scenes' rate: ``{"clips": n, "rates": {rate: n}, "fs": scenes' rate}``; a 16 kHz clip is
    empty above 8 kHz however it is resampled. None when the plan or the corpus is not
    there to read the headers from."""
    import soundfile as sf  # libsndfile: only the band-limit count reads headers

    layout = Layout(root)
    try:
        config = local_roots(read_plan_doc(layout)["config"], layout.root)
        corpus, fs = config["corpus"]["dir"], int(config["audio"]["fs"])
    except (TselError, OSError, KeyError, TypeError, ValueError):
        return None
    corpus = layout.demo_corpus if corpus.startswith("builtin:") else corpus
    rates: Counter = Counter()
    for rel in audio.values():
        if not is_regular(os.path.join(corpus, rel)):
            return None  # gone, or a FIFO libsndfile would wait on
        try:
            rate = sf.info(os.path.join(corpus, rel)).samplerate
        except (sf.LibsndfileError, RuntimeError, OSError):
            return None  # the corpus moved or is partly gone: no count rather than a wrong one
        if rate < fs:
            rates[int(rate)] += 1
    return {"clips": int(sum(rates.values())), "rates": dict(sorted(rates.items())), "fs": fs}


def dataset_stats(root: str, splits=None, tallied: dict | None = None) -> dict:
    """{split: split_stats} for the given splits (default: all, in dataset.json order); a
    dataset still being made gives the statistics of its finished shards. ``tallied``:
    {split: SplitTally} of splits a caller has read already (they are not read again)."""
    tallied = tallied or {}
    return {s: tallied[s].result() if s in tallied else split_stats(root, s)
            for s in (list(splits) if splits else list_splits(root, unfinished=True))}


def _line(name: str, s: dict, unit: str = "", fmt: str = ".2f") -> str:
    if not s.get("n"):
        return f"  {name:<26} -"
    return (f"  {name:<26} {s['min']:{fmt}} / {s['median']:{fmt}} / {s['mean']:{fmt}} / {s['max']:{fmt}} {unit}"
            f"  (n={s['n']})")


def _sparkline(counts) -> str:
    blocks = " ▁▂▃▄▅▆▇█"
    c = np.asarray(counts, dtype=float)
    if c.max() <= 0:
        return ""
    return "".join(blocks[int(round(8 * x / c.max()))] for x in c)


def format_text(stats: dict) -> str:
    """Human-readable report of :func:`dataset_stats` output."""
    out = []
    for name, s in stats.items():
        cl = s["clips"]
        out.append(f"split {name}: {s['scenes']} scenes")
        out.append("  scenarios: " + ", ".join(f"{k} {v}" for k, v in sorted(s["scenarios"].items()))
                   + "   motion: " + ", ".join(f"{k} {v}" for k, v in sorted(s["motion"].items()))
                   + f"   moving fraction {s['moving_fraction']:.2f}")
        out.append(f"  clips: {cl['used']} used ({cl['uses']} uses), {cl['reused']} reused (max {cl['max_uses']} uses); "
                   f"{cl['target_clips']} as target, {cl['target_reused']} of them more than once")
        narrow = cl.get("target_band_limited")
        if narrow and narrow["clips"]:
            out.append(f"  target clips band-limited: {narrow['clips']} of {cl['target_clips']} "
                       f"({band_limited_text(narrow['clips'], narrow['rates'], narrow['fs']).partition('(')[2]}")
        h = s["target_azimuth_hist"]
        out.append(f"  target azimuth, {h['bin_deg']} deg bins from -180: |{_sparkline(h['counts'])}|")
        out.append("  " + " " * 26 + " min / median / mean / max")
        out.append(_line("separation (deg)", s["separation_deg"], fmt=".1f"))
        out.append(_line("target distance (m)", s["target_distance_m"]))
        out.append(_line("interferer distance (m)", s["interferer_distance_m"]))
        for ax in ("x", "y", "z"):
            out.append(_line(f"room {ax} (m)", s["room_m"][ax]))
        out.append(_line("room volume (m3)", s["room_m"]["volume_m3"], fmt=".1f"))
        out.append(_line("RT60 requested (s)", s["rt60_s"]["requested"]))
        out.append(_line("RT60 measured (s)", s["rt60_s"]["measured"]))
        out.append(_line("RT60 measured-requested", s["rt60_s"]["measured_minus_requested"]))
        out.append(_line("target level (dBFS)", s["levels_db"]["target_dbfs"], fmt=".1f"))
        out.append(_line("TIR (dB)", s["levels_db"]["tir"], fmt=".1f"))
        if s["levels_db"]["snr"].get("n"):
            out.append(_line("SNR against all noise (dB)", s["levels_db"]["snr"], fmt=".1f"))
        out.append(_line("peak (dBFS)", s["levels_db"]["peak_dbfs"], fmt=".1f"))
        out.append(_line("target active fraction", s["target_active_fraction"]))
        out.append(_line("target elevation (deg)", s["target_elevation_deg"], fmt=".1f"))
        out.append(_line("moving source speed (deg/s)", s["moving_sources"]["speed_deg_s"], fmt=".1f"))
        out.append(_line("query length (words)", s["query_words"], fmt=".0f"))
        d = s.get("descriptors")
        if d:
            out.append(_line("target DRR (dB)", d["target_drr_db"], fmt=".1f"))
            out.append(_line("target C50 (dB)", d["target_c50_db"], fmt=".1f"))
            out.append(_line("target T30 (s)", d["target_t30_s"]))
            out.append("  sources' motion: " + ", ".join(f"{k} {v}" for k, v in d["source_motion"].items()))
        out += _query_lines(s["queries"])
        out += _recorded_lines(s.get("recorded"))
    return "\n".join(out)


def _recorded_lines(r: dict | None) -> list[str]:
    if not r:
        return []
    out = []
    if "windows" in r:
        skipped = r.get("skipped") or {}
        out.append(f"  recorded: {r['kept']} scenes kept of {r['candidates']} targets in {r['windows']} windows of "
                   f"{r['recordings']} recordings; {r['too_short']} sources active less than recorded.min_active")
        out += [f"  skipped {n}: {why}" for why, n in skipped.items()] or ["  skipped: none"]
    out.append("  target classes: " + ", ".join(f"{k} {v}" for k, v in r["target_classes"].items()))
    return out


def plot_stats(stats: dict, path: str, dpi: int = 100) -> str:
    """Histograms of the main quantities, one colour per split, to a PNG file. Each bar
    height is the share of the split's values in that bin (%), so splits of any size
    compare; the panel titles say what is counted."""
    import matplotlib  # seconds to import: only --png pays it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [("target_az", "target azimuth (deg)", np.arange(-180, 181, AZ_BIN), "scenes"),
              ("target_el", "target elevation (deg)", np.arange(-90, 91, 10), "scenes"),
              ("separation", "target-interferer separation (deg)", np.arange(0, 181, 10), "scenes"),
              ("target_dist", "target distance (m)", 20, "scenes"),
              ("volume", "room volume (m³)", 20, "scenes"), ("rt60", "RT60 requested (s)", 20, "scenes"),
              ("rt60_measured", "RT60 measured (s)", 20, "scenes"), ("tir", "TIR (dB)", 20, "interferers"),
              ("speed", "speed of moving sources (deg/s)", 20, "moving sources"),
              ("target_active", "target active fraction", np.linspace(0, 1, 21), "scenes"),
              ("query_words", "query length (words)", 1, "scenes")]  # 1: one bin per word
    fig, axes = plt.subplots(3, 4, figsize=(17, 10))
    axes = axes.ravel()

    def values(s, key):
        return np.asarray([x for x in s["raw"][key] if x is not None and np.isfinite(x)], dtype=float)

    for ax, (key, title, bins, unit) in zip(axes, panels):
        if np.isscalar(bins):  # the same edges for every split, so they compare
            every = np.concatenate([values(s, key) for s in stats.values()])
            if bins == 1:
                bins = np.arange(0.5, (every.max() if every.size else 1) + 1.5)
            else:
                bins = np.histogram_bin_edges(every, bins) if every.size else bins
        for name, s in stats.items():
            v = values(s, key)
            if v.size:
                ax.hist(v, bins=bins, histtype="step", lw=1.6, weights=np.full(v.size, 100.0 / v.size),
                        label=f"{name} ({v.size})")
        ax.set_title(title, fontsize=10)
        ax.set_ylabel(f"% of {unit}", fontsize=8)
        ax.tick_params(labelsize=8)
        if ax.has_data():
            ax.legend(fontsize=7)
        else:
            ax.text(0.5, 0.5, "no values", ha="center", va="center", transform=ax.transAxes, color="0.5")
    # what moves: share of each split's scenes per kind, bars side by side
    ax = axes[len(panels)]
    width = 0.8 / max(len(stats), 1)
    for i, (name, s) in enumerate(stats.items()):
        n = max(len(s["raw"]["moves"]), 1)
        shares = [100.0 * s["raw"]["moves"].count(k) / n for k in MOTION_KINDS]
        ax.bar(np.arange(len(MOTION_KINDS)) + (i - (len(stats) - 1) / 2) * width, shares, width, label=name)
    ax.set_xticks(range(len(MOTION_KINDS)))
    ax.set_xticklabels(MOTION_KINDS, fontsize=8)
    ax.set_ylabel("% of scenes", fontsize=8)
    ax.set_title("what moves in a scene", fontsize=10)
    ax.tick_params(labelsize=8)
    ax.legend(fontsize=7)
    fig.suptitle("dataset statistics per split (share of each split's values per bin)")
    fig.tight_layout()
    try:
        with atomic_output(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return path
