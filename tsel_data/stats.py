"""Dataset statistics per split, from the labels and JSON records (no audio is read).

Per split: scene count, scenarios, moving fraction, clip use and reuse, a 10° histogram
of target azimuths (one value per scene: the circular mean over its active frames),
angular separation between the target and the nearest other directional source,
source distances, room sizes, RT60 requested and measured, levels (target level, TIR,
peak), the target's active share of frames, query length in words, and the mix of
query types, relations and pairings (:func:`query_mix`).
"""
from __future__ import annotations

from collections import Counter

import numpy as np

from .atomic import atomic_output
from .geometry import azimuth_difference, circular_mean
from .store.reader import list_splits, open_dataset

AZ_BIN = 10


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
    with open_dataset(root, split) as ds:
        scenes = list(ds.iter_labels())  # labels only: small
    raw = {k: [] for k in ("target_az", "separation", "target_dist", "interferer_dist", "room_x", "room_y",
                           "room_z", "volume", "rt60", "rt60_measured", "target_level", "tir", "peak",
                           "target_active", "query_words")}
    clip_uses, target_clips = Counter(), Counter()
    scenarios, motions = Counter(), Counter()
    moving = 0
    for sc in scenes:
        rec = sc.record
        scenarios[rec.scenario] += 1
        motions[rec.motion] += 1
        moving += any(s.moving for s in rec.sources) or rec.motion == "moving"
        for k, s in enumerate(rec.sources):
            if s.clip_id is not None:
                clip_uses[s.clip_id] += 1
                if k == 0:
                    target_clips[s.clip_id] += 1
            if k > 0 and s.tir_db is not None:
                raw["tir"].append(s.tir_db)
        act = sc.active.astype(bool)
        t_az = _mean_az(sc.azimuth[0], act[0])
        raw["target_az"].append(t_az)
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
    n = len(scenes)
    az = np.asarray([a for a in raw["target_az"] if a is not None])
    hist, _ = np.histogram(az, bins=np.arange(-180, 181, AZ_BIN))
    pairs = [(r, m) for r, m in zip(raw["rt60"], raw["rt60_measured"]) if r is not None and m is not None]
    return {
        "split": split,
        "scenes": n,
        "scenarios": dict(scenarios),
        "motion": dict(motions),
        "moving_fraction": moving / n if n else float("nan"),
        "clips": {"used": len(clip_uses), "uses": int(sum(clip_uses.values())),
                  "reused": sum(1 for c in clip_uses.values() if c > 1),
                  "max_uses": max(clip_uses.values(), default=0),
                  "target_clips": len(target_clips),
                  "target_reused": sum(1 for c in target_clips.values() if c > 1)},
        "target_azimuth_hist": {"bin_deg": AZ_BIN, "edges_from": -180, "counts": hist.tolist()},
        "separation_deg": _summ(raw["separation"]),
        "target_distance_m": _summ(raw["target_dist"]),
        "interferer_distance_m": _summ(raw["interferer_dist"]),
        "room_m": {"x": _summ(raw["room_x"]), "y": _summ(raw["room_y"]), "z": _summ(raw["room_z"]),
                   "volume_m3": _summ(raw["volume"])},
        "rt60_s": {"requested": _summ(raw["rt60"]), "measured": _summ(raw["rt60_measured"]),
                   "measured_minus_requested": _summ([m - r for r, m in pairs])},
        "levels_db": {"target_dbfs": _summ(raw["target_level"]), "tir": _summ(raw["tir"]),
                      "peak_dbfs": _summ([20 * np.log10(p) for p in raw["peak"] if p])},
        "target_active_fraction": _summ(raw["target_active"]),
        "query_words": _summ(raw["query_words"]),
        "queries": query_mix(sc.record for sc in scenes),
        "raw": raw,
    }


def query_mix(records) -> dict:
    """Counts of query types, relations (``type:relation``), pairings, and of scenes whose
    query fell back from the type drawn (``wanted->got``; docs/queries.md)."""
    types, relations, pairings, fallbacks = Counter(), Counter(), Counter(), Counter()
    for rec in records:
        types[rec.query_type] += 1
        pairings[rec.pairing] += 1
        if rec.query_relation:
            relations[f"{rec.query_type}:{rec.query_relation}"] += 1
        if rec.query_wanted and rec.query_wanted != rec.query_type:
            fallbacks[f"{rec.query_wanted}->{rec.query_type}"] += 1
    return {"types": dict(types), "relations": dict(sorted(relations.items())), "pairing": dict(pairings),
            "fallbacks": dict(sorted(fallbacks.items()))}


def _query_lines(q: dict) -> list[str]:
    def counts(d):
        return ", ".join(f"{k} {v}" for k, v in sorted(d.items())) or "none"

    lines = [f"  queries: {counts(q['types'])}   pairing: {counts(q['pairing'])}"]
    if q["relations"]:
        lines.append(f"  relations: {counts(q['relations'])}")
    if q["fallbacks"]:
        lines.append(f"  fell back (drawn->used): {counts(q['fallbacks'])}")
    return lines


def dataset_stats(root: str, splits=None) -> dict:
    """{split: split_stats} for the given splits (default: all, in dataset.json order)."""
    return {s: split_stats(root, s) for s in (list(splits) if splits else list_splits(root))}


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
        out.append(_line("peak (dBFS)", s["levels_db"]["peak_dbfs"], fmt=".1f"))
        out.append(_line("target active fraction", s["target_active_fraction"]))
        out.append(_line("query length (words)", s["query_words"], fmt=".0f"))
        out += _query_lines(s["queries"])
    return "\n".join(out)


def plot_stats(stats: dict, path: str, dpi: int = 100) -> str:
    """Histograms of the main quantities, one colour per split, to a PNG file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [("target_az", "target azimuth (deg)", np.arange(-180, 181, AZ_BIN)),
              ("separation", "target-interferer separation (deg)", np.arange(0, 181, 10)),
              ("target_dist", "target distance (m)", 20), ("volume", "room volume (m³)", 20),
              ("rt60", "RT60 requested (s)", 20), ("rt60_measured", "RT60 measured (s)", 20),
              ("tir", "TIR (dB)", 20), ("query_words", "query length (words)", np.arange(0.5, 41.5, 1))]
    fig, axes = plt.subplots(2, 4, figsize=(16, 6.5))
    def values(s, key):
        return np.asarray([x for x in s["raw"][key] if x is not None and np.isfinite(x)], dtype=float)

    for ax, (key, title, bins) in zip(axes.ravel(), panels):
        if np.isscalar(bins):  # the same edges for every split, so they compare
            every = np.concatenate([values(s, key) for s in stats.values()])
            bins = np.histogram_bin_edges(every, bins) if every.size else bins
        for name, s in stats.items():
            v = values(s, key)
            if v.size:
                ax.hist(v, bins=bins, histtype="step", lw=1.6, density=True, label=f"{name} ({v.size})")
        ax.set_title(title, fontsize=10)
        ax.tick_params(labelsize=8)
        if ax.has_data():
            ax.legend(fontsize=7)
    fig.suptitle("dataset statistics per split (normalised histograms)")
    fig.tight_layout()
    try:
        with atomic_output(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return path
