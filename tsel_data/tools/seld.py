"""The DCASE SELD metrics, as DCASE 2024 Task 3 defines them, for the DCASE layout.

Frame-level (100 ms label frames), per class c and frame: the R reference and P
predicted events of the class are matched by the Hungarian algorithm on their angular
distance; of the K = min(P, R) matched pairs, L are *spatial* false positives (angle
above the threshold, 20°, or relative distance error above its threshold, 1.0); then

    TP += K - L    FP_spatial += L    FP += max(0, P - R)    FN += max(0, R - P)
    LE sum += the K angles    RDE sum += the K |d̂ - d| / d    DE_TP += K    DE_FN += FN

and per frame, over classes, S = min(FP + L, FN), D = max(0, FN - FP - L),
I = max(0, FP + L - FN). Scores: ER = (S + D + I) / N_ref; per class the
location-dependent F = TP / (TP + FP_spatial + (FP + FN) / 2), the localisation error
LE = LE sum / DE_TP (degrees), the localisation recall LR = DE_TP / (DE_TP + DE_FN),
the relative distance error RDE = RDE sum / DE_TP and DE the mean distance error (m);
the macro average over the classes that occur (F, LR: mean; LE, DE, RDE: mean over
classes with a matched pair; DCASE averages over its 13 classes, all of which occur in
its evaluation sets, where a scene of ours may hold no interferer), and the SELD score of 2024, mean(1 - F, LE / 180, RDE) per class, then
over classes (without distances, 2023's: mean(ER, 1 - F, LE / 180, 1 - LR)). Classes of a tsel export: 0 the query's target, 1 the other directional
sources (export/dcase.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

ANGLE_THRESHOLD = 20.0  # degrees
RELDIST_THRESHOLD = 1.0  # relative distance error
_EPS = np.finfo(float).eps


@dataclass
class _Counts:
    tp: float = 0.0
    fp: float = 0.0
    fp_spatial: float = 0.0
    fn: float = 0.0
    n_ref: float = 0.0
    angle: float = 0.0
    dist: float = 0.0
    reldist: float = 0.0
    matched: float = 0.0  # DE_TP
    missed: float = 0.0  # DE_FN
    with_dist: float = 0.0  # matched pairs that both have a distance
    seen: bool = False  # a reference or a prediction of the class occurred


@dataclass
class SeldScores:
    """ER, F, LE (deg), LR, DE (m), RDE, SELD of one split, macro over classes, with
    the same per class in ``classes`` ({class: {...}}); frames scored."""

    er: float
    f: float
    le: float
    lr: float
    de: float
    rde: float
    seld: float
    frames: int
    classes: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"er": self.er, "f": self.f, "le": self.le, "lr": self.lr, "de": self.de, "rde": self.rde,
                "seld": self.seld, "frames": self.frames, "classes": self.classes}

    def format_text(self, names: dict | None = None) -> str:
        names = names or {}
        lines = [f"DCASE 2024 SELD metrics over {self.frames} frames of 100 ms (location-dependent at "
                 f"{ANGLE_THRESHOLD:g}° and relative distance {RELDIST_THRESHOLD:g}; macro over classes)",
                 f"{'class':<16}{'F':>8}{'LE(deg)':>9}{'LR':>8}{'DE(m)':>8}{'RDE':>8}{'SELD':>8}{'refs':>8}"]

        def row(name, r, refs):
            return (f"{name:<16}{100 * r['f']:>7.1f}%{r['le']:>9.2f}{100 * r['lr']:>7.1f}%{r['de']:>8.2f}"
                    f"{r['rde']:>8.3f}{r['seld']:>8.3f}{refs:>8}")

        for c, r in self.classes.items():
            lines.append(row(f"{c} {names.get(c, '')}".strip(), r, r["n_ref"]))
        lines.append(row("macro", self.to_dict(), sum(r["n_ref"] for r in self.classes.values())))
        lines.append(f"error rate ER {self.er:.3f}")
        return "\n".join(lines)


def angular_distance(az1, el1, az2, el2) -> np.ndarray:
    """Great-circle angle (degrees) between directions given in degrees."""
    a1, e1, a2, e2 = (np.radians(np.asarray(v, dtype=np.float64)) for v in (az1, el1, az2, el2))
    u = np.stack(np.broadcast_arrays(np.cos(e1) * np.cos(a1), np.cos(e1) * np.sin(a1), np.sin(e1)), -1)
    v = np.stack(np.broadcast_arrays(np.cos(e2) * np.cos(a2), np.cos(e2) * np.sin(a2), np.sin(e2)), -1)
    # atan2 of |u × v| and u · v: exact near 0° and 180°, where arccos of the dot loses digits
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.sum(u * v, axis=-1)))


class SeldAccumulator:
    """Add frames with :meth:`add_frame`, then :meth:`scores`."""

    def __init__(self, classes, angle_threshold: float = ANGLE_THRESHOLD,
                 reldist_threshold: float = RELDIST_THRESHOLD):
        self.counts = {c: _Counts() for c in classes}
        self.angle_t, self.reldist_t = angle_threshold, reldist_threshold
        self.s = self.d = self.i = 0.0
        self.frames = 0

    def add_frame(self, ref: dict, pred: dict) -> None:
        """One frame: {class: [(azimuth, elevation, distance m or nan), ...]} each."""
        from scipy.optimize import linear_sum_assignment  # only evaluation needs it

        frame_fp = frame_fn = 0
        for c in set(ref) | set(pred):
            if c not in self.counts:
                self.counts[c] = _Counts()
            k = self.counts[c]
            k.seen = True
            r, p = np.asarray(ref.get(c, []), float).reshape(-1, 3), np.asarray(pred.get(c, []), float).reshape(-1, 3)
            k.n_ref += len(r)
            if len(r) and len(p):
                ang = angular_distance(r[:, None, 0], r[:, None, 1], p[None, :, 0], p[None, :, 1])
                rows, cols = linear_sum_assignment(ang)
                a = ang[rows, cols]
                dr, dp = r[rows, 2], p[cols, 2]
                both = np.isfinite(dr) & np.isfinite(dp)
                rel = np.where(both, np.abs(dp - dr) / (dr + _EPS), 0.0)
                spatial = int(np.sum((a > self.angle_t) | (both & (rel > self.reldist_t))))
                matched = len(rows)
                fn, fp_inf = max(0, len(r) - len(p)), max(0, len(p) - len(r))
                k.tp += matched - spatial
                k.fp_spatial += spatial
                k.fp += fp_inf
                k.fn += fn
                k.angle += float(a.sum())
                k.dist += float(np.abs(dp - dr)[both].sum())
                k.reldist += float(rel[both].sum())
                k.with_dist += int(both.sum())
                k.matched += matched
                k.missed += fn
                frame_fp += fp_inf + spatial
                frame_fn += fn
            elif len(r):
                k.fn += len(r)
                k.missed += len(r)
                frame_fn += len(r)
            elif len(p):
                k.fp += len(p)
                frame_fp += len(p)
        self.s += min(frame_fp, frame_fn)
        self.d += max(0, frame_fn - frame_fp)
        self.i += max(0, frame_fp - frame_fn)
        self.frames += 1

    def scores(self) -> SeldScores:
        n_ref = sum(k.n_ref for k in self.counts.values())
        er = (self.s + self.d + self.i) / (n_ref + _EPS)
        with_dist = any(k.with_dist for k in self.counts.values())
        per = {}
        for c, k in sorted(self.counts.items()):
            if not k.seen:
                continue
            f = k.tp / (_EPS + k.tp + k.fp_spatial + 0.5 * (k.fp + k.fn))
            le = k.angle / k.matched if k.matched else math.nan
            de = k.dist / k.with_dist if k.with_dist else math.nan
            rde = k.reldist / k.with_dist if k.with_dist else math.nan
            lr = k.matched / (_EPS + k.matched + k.missed)
            # 2024 with distances; without any, the 2023 score (ER and LR in it)
            parts = [1 - f, le / 180.0, rde] if with_dist else [er, 1 - f, le / 180.0, 1 - lr]
            seld = float(np.nanmean(parts))
            # plain floats: the scores print and serialise as numbers, not np.float64(...)
            per[c] = {"f": float(f), "le": float(le), "lr": float(lr), "de": float(de), "rde": float(rde),
                      "seld": seld, "n_ref": int(k.n_ref)}

        def mean(key, skip_nan):
            v = np.asarray([p[key] for p in per.values()], dtype=np.float64)
            if skip_nan:
                v = v[np.isfinite(v)]
            return float(v.mean()) if v.size else math.nan

        return SeldScores(er=float(er), f=mean("f", False), le=mean("le", True), lr=mean("lr", False),
                          de=mean("de", True), rde=mean("rde", True), seld=mean("seld", True), frames=self.frames,
                          classes=per)


def frames_of(rows, n_frames: int) -> list[dict]:
    """DCASE rows (frame, class, source, azimuth °, elevation °[, distance cm]) -> one
    {class: [(az, el, distance m)]} per frame; rows past ``n_frames`` are left out, as
    the DCASE scorer reads only the reference's frames."""
    out: list[dict] = [{} for _ in range(n_frames)]
    for row in rows:
        frame, cls = int(row[0]), int(row[1])
        if 0 <= frame < n_frames:
            dist = float(row[5]) / 100.0 if len(row) > 5 else math.nan
            out[frame].setdefault(cls, []).append((float(row[3]), float(row[4]), dist))
    return out
