"""The paper's metric: mean absolute azimuth error of the target, with wrap-around.

Error between predicted and true azimuth: ``e = min(|d|, 360 - |d|)``, ``d = φ̂ - φ``,
in degrees, so e ∈ [0, 180]. Units of evaluation (Zhao et al., "Text-Queried Target
Sound Event Localization"):

- **static target**: one unit per scene (clip), compared to its static azimuth;
- **moving target**: one unit per *active* frame of the target (all frames if the
  target is never marked active).

Rows are given for the whole split and per scenario, motion, query type, query type
and relation (``relational:loudest``), and pairing (docs/queries.md).

A group's MAE and accuracies (share of units with e ≤ 5°, 10°, 20°, to within
:data:`ACC_TOLERANCE`, so that a prediction exactly 5° off counts at 5° despite rounding)
pool its units.
For a purely static or purely moving split this is exactly the paper's number; in a
mixed group each moving scene contributes one unit per active frame, so the per-scene
MAE (the mean of each scene's mean error) is given beside it. The DCASE SELD metrics of
a DCASE-layout prediction: :mod:`tsel_data.tools.evaluate_dcase`.

Prediction file: JSON Lines, one object per scene of the split (docs/reader.md)::

    {"scene_id": "test-000000", "azimuth": -37.5}                 one azimuth per clip
    {"scene_id": "test-000001", "azimuth": [12.0, 13.1, ...]}     one per label frame (F)
    {"scene_id": "test-000002", "distribution": [[...360...], ...]}  per frame, argmax
    {"scene_id": "test-000003", "distribution": [...360...]}      one per clip, argmax

A distribution's bin k stands for azimuth k degrees (k = 180..359 are -180..-1). A
per-frame prediction of a static target is reduced to one azimuth by the circular mean
over the target's active frames; a single azimuth for a moving target is compared with
every active frame.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from ..core.files import check_input
from ..core.geometry import azimuth_difference, circular_mean
from ..errors import DatasetError, PredictionError
from ..store.reader import open_dataset
from .blind import CLOSE_DEG, blind_predictions
from .labels import decode_distribution

THRESHOLDS = (5.0, 10.0, 20.0)
ACC_TOLERANCE = 1e-6  # degrees: an error of exactly T can compute as T + 3e-14 (circular means); it counts for acc@T
MAX_AZIMUTH = 360.0 * 1000  # degrees: any real prediction is far inside; larger ones are unit mistakes
__all__ = ["PredictionError", "Prediction", "EvalResult", "evaluate", "read_predictions", "parse_prediction",
           "scene_errors", "summarise", "write_predictions"]


@dataclass
class Prediction:
    """One scene's prediction: ``azimuth`` float64 [] (clip) or [F] (per frame), degrees."""

    scene_id: str
    azimuth: np.ndarray
    line: int = 0

    @property
    def per_frame(self) -> bool:
        return self.azimuth.ndim == 1


@dataclass
class EvalResult:
    """Scores of one split. ``overall``/``by_*`` rows: scenes, units, mae, acc@5/10/20."""

    split: str
    overall: dict
    by_scenario: dict = field(default_factory=dict)
    by_motion: dict = field(default_factory=dict)
    per_scene: list = field(default_factory=list)
    by_query: dict = field(default_factory=dict)
    by_relation: dict = field(default_factory=dict)
    by_pairing: dict = field(default_factory=dict)
    by_snr: dict = field(default_factory=dict)  # only for datasets with [noise]
    blind: dict = field(default_factory=dict)  # answers made without listening (tools/blind.py)
    blind_flag: str = ""  # set when one of them scores close to the predictions


    def to_dict(self, per_scene: bool = True) -> dict:
        d = {"split": self.split, "overall": self.overall, "by_scenario": self.by_scenario,
             "by_motion": self.by_motion, "by_query": self.by_query, "by_relation": self.by_relation,
             "by_pairing": self.by_pairing}
        if self.by_snr:
            d["by_snr"] = self.by_snr
        if self.blind:
            d["blind"] = self.blind
            d["blind_flag"] = self.blind_flag
        if per_scene:
            d["per_scene"] = self.per_scene
        return d

    def format_text(self) -> str:
        head = f"{'group':<32}{'scenes':>7}{'units':>8}{'MAE(deg)':>10}{'per scene':>11}" + "".join(
            f"{'acc@' + format(t, 'g'):>9}" for t in THRESHOLDS)
        lines = [f"split {self.split}: mean absolute azimuth error of the target (wrap-around)", head]

        def row(name, r):
            accs = "".join(f"{100 * r[f'acc{int(t)}']:>8.1f}%" for t in THRESHOLDS)
            return f"{name:<32}{r['scenes']:>7}{r['units']:>8}{r['mae']:>10.2f}{r['scene_mae']:>11.2f}{accs}"

        lines.append(row("all", self.overall))
        for title, groups in (("scenario", self.by_scenario), ("motion", self.by_motion), ("query", self.by_query),
                              ("relation", self.by_relation), ("pairing", self.by_pairing), ("snr", self.by_snr)):
            for name, r in groups.items():
                lines.append(row(f"{title}={name}", r))
        if self.blind:
            lines.append("blind answers, from the train split's labels and the query (no audio):")
            for name, r in self.blind.items():
                lines.append(row(f"blind={name}", r))
        if self.blind_flag:
            lines.append(self.blind_flag)
        return "\n".join(lines)


def read_predictions(path: str) -> dict[str, Prediction]:
    """Parse a JSONL prediction file (PredictionError naming the line on any problem)."""
    preds: dict[str, Prediction] = {}
    check_input(path, PredictionError, "give the prediction file itself")  # a FIFO or device would block
    try:
        with open(path, "rb") as fh:
            raw_lines = fh.read().split(b"\n")
    except OSError as e:
        raise PredictionError(f"{path}: cannot read prediction file ({e.strerror})") from None
    for n, raw in enumerate(raw_lines, 1):
        if not raw.strip():
            continue
        where = f"{path}:{n}"
        try:
            line = raw.decode("utf-8")
        except UnicodeDecodeError as e:
            raise PredictionError(f"{where}: not UTF-8 (invalid byte at offset {e.start}); write the file as "
                                  f"UTF-8 JSON Lines") from None
        try:
            obj = json.loads(line)
        except json.JSONDecodeError as e:
            raise PredictionError(f"{where}: not valid JSON ({e.msg})") from None
        except ValueError:  # an integer of thousands of digits (Python refuses to convert it)
            raise PredictionError(f"{where}: a number with thousands of digits; azimuths are degrees") from None
        except RecursionError:
            raise PredictionError(f"{where}: lists nested too deeply; an azimuth is a number, or a list of "
                                  f"numbers per frame") from None
        p = parse_prediction(obj, where)
        p.line = n
        if p.scene_id in preds:
            raise PredictionError(f"{where}: scene {p.scene_id!r} predicted twice (first on line "
                                  f"{preds[p.scene_id].line}); keep one line per scene")
        preds[p.scene_id] = p
    if not preds:
        raise PredictionError(f"{path}: no predictions (expected one JSON object per line)")
    return preds


def _numeric(v) -> bool:
    """Numbers, or (nested) lists of numbers; booleans are not numbers here."""
    if isinstance(v, list):
        return all(_numeric(x) for x in v)
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def parse_prediction(obj, where: str = "prediction") -> Prediction:
    """One JSON object -> :class:`Prediction` (see the module docstring for the forms)."""
    if not isinstance(obj, dict) or not isinstance(obj.get("scene_id"), str):
        raise PredictionError(f"{where}: expected an object with a string \"scene_id\"")
    has_az, has_dist = "azimuth" in obj, "distribution" in obj
    if has_az == has_dist:
        raise PredictionError(f"{where}: give exactly one of \"azimuth\" or \"distribution\"")
    value = obj["azimuth"] if has_az else obj["distribution"]
    if not _numeric(value):  # not true, "12" or null: JSON numbers only
        raise PredictionError(f"{where}: values must be JSON numbers (or lists of them), not strings, booleans "
                              f"or null")
    try:
        val = np.asarray(value, dtype=np.float64)
    except OverflowError:  # an integer of 400 digits: JSON allows it, a float does not hold it
        raise PredictionError(f"{where}: a number too large for a float; azimuths are degrees") from None
    except (TypeError, ValueError):
        raise PredictionError(f"{where}: values must be numbers (or lists of numbers), each list the same "
                              f"length") from None
    if has_dist:
        if val.ndim not in (1, 2) or val.shape[-1] != 360:
            raise PredictionError(f"{where}: \"distribution\" must be 360 numbers or a list of them per frame, "
                                  f"got shape {list(val.shape)}")
        if not np.isfinite(val).all():
            raise PredictionError(f"{where}: \"distribution\" contains NaN or infinity")
        if (val.max(axis=-1) <= val.min(axis=-1)).any():  # all equal (e.g. all zero): no argmax to take
            raise PredictionError(f"{where}: \"distribution\" is flat (every score equal) in a frame; it names no "
                                  f"azimuth")
        val = decode_distribution(val)
    else:
        if val.ndim > 1 or val.size == 0:
            raise PredictionError(f"{where}: \"azimuth\" must be a number or a list of numbers (one per frame)")
        if not np.isfinite(val).all():
            raise PredictionError(f"{where}: \"azimuth\" contains NaN, infinity or null")
        if (np.abs(val) > MAX_AZIMUTH).any():  # 1e308 wraps to a number, but not to a prediction
            raise PredictionError(f"{where}: \"azimuth\" must be degrees within ±{MAX_AZIMUTH:g}, got "
                                  f"{float(val.flat[np.argmax(np.abs(val))])!r}")
    return Prediction(obj["scene_id"], val)


def scene_errors(pred: Prediction, azimuth: np.ndarray, active: np.ndarray, moving: bool) -> np.ndarray:
    """Errors (deg) of one scene's units: [1] for a static target, [n active frames] if moving.

    azimuth, active: the target's labels [F].
    """
    n_frames = azimuth.shape[0]
    if pred.per_frame and pred.azimuth.shape[0] != n_frames:
        raise PredictionError(f"scene {pred.scene_id!r} (line {pred.line}): {pred.azimuth.shape[0]} frame "
                              f"azimuths, but the scene has {n_frames} label frames")
    use = np.asarray(active, bool) & np.isfinite(azimuth)
    if not use.any():
        use = np.isfinite(azimuth)
    if moving:
        est = pred.azimuth[use] if pred.per_frame else np.full(int(use.sum()), float(pred.azimuth))
        return azimuth_difference(est, azimuth[use])
    truth = circular_mean(azimuth[use])
    est = circular_mean(pred.azimuth[use]) if pred.per_frame else float(pred.azimuth)
    return np.atleast_1d(azimuth_difference(est, truth))


def summarise(errors: list[np.ndarray]) -> dict:
    """Pool units of several scenes -> {scenes, units, mae, scene_mae, acc5, acc10, acc20}:
    ``mae`` over units (the paper's), ``scene_mae`` the mean of each scene's mean error
    (every scene weighs the same, a moving one as much as a static one)."""
    e = np.concatenate(errors) if errors else np.zeros(0)
    means = [float(x.mean()) for x in errors if x.size]
    row = {"scenes": len(errors), "units": int(e.size), "mae": float(e.mean()) if e.size else float("nan"),
           "scene_mae": float(np.mean(means)) if means else float("nan")}
    for t in THRESHOLDS:
        row[f"acc{int(t)}"] = float((e <= t + ACC_TOLERANCE).mean()) if e.size else float("nan")
    return row


def evaluate(root: str, split: str, predictions) -> EvalResult:
    """Score ``predictions`` (a JSONL path or {scene_id: Prediction}) on one split."""
    preds = read_predictions(predictions) if isinstance(predictions, (str, bytes)) or hasattr(
        predictions, "__fspath__") else dict(predictions)
    with open_dataset(root, split) as ds:
        ids = ds.scene_ids()
        scenes = list(ds.iter_labels())  # labels only: small
    known = set(ids)
    unknown = [s for s in preds if s not in known]
    if unknown:
        raise PredictionError(f"{len(unknown):,} predicted scene id(s) are not in split {split!r}, e.g. "
                              f"{unknown[0]!r}; predict the scenes of `--split {split}`")
    missing = [s for s in ids if s not in preds]
    if missing:
        raise PredictionError(f"{len(missing):,} of {len(ids):,} scenes of split {split!r} have no prediction, e.g. "
                              f"{missing[0]!r}; the file must predict every scene")
    per_scene, groups_sc, groups_mo, all_err = [], {}, {}, []
    groups_q, groups_rel, groups_pair, groups_snr = {}, {}, {}, {}
    for scene in scenes:
        moving = scene.target_moving
        err = scene_errors(preds[scene.scene_id], scene.azimuth[0].astype(np.float64), scene.active[0], moving)
        scenario = scene.record.scenario
        # the unit of scoring follows the target, so the group does too (a static target
        # beside a moving interferer is scored once per clip, with the static ones)
        motion = "moving" if moving else "static"
        all_err.append(err)
        groups_sc.setdefault(scenario, []).append(err)
        groups_mo.setdefault(motion, []).append(err)
        groups_q.setdefault(scene.query_type, []).append(err)
        if scene.query_relation:
            groups_rel.setdefault(f"{scene.query_type}:{scene.query_relation}", []).append(err)
        groups_pair.setdefault(scene.pairing, []).append(err)
        if scene.record.noise:
            groups_snr.setdefault(snr_group(scene.record.noise), []).append(err)
        per_scene.append({"scene_id": scene.scene_id, "scenario": scenario, "motion": motion,
                          "query_type": scene.query_type, "query_relation": scene.query_relation,
                          "pairing": scene.pairing, "unit": "frame" if moving else "clip", "units": int(err.size),
                          "error": float(err.mean()) if err.size else float("nan")})
    if not all_err:
        raise DatasetError(f"{root}: split {split!r} has no scenes")
    overall = summarise(all_err)
    blind = {name: summarise([scene_errors(Prediction(s.scene_id, np.float64(answer[s.scene_id])),
                                           s.azimuth[0].astype(np.float64), s.active[0], s.target_moving)
                              for s in scenes])
             for name, answer in blind_predictions(root, split).items()}
    return EvalResult(
        split=split,
        overall=overall,
        by_scenario={k: summarise(v) for k, v in sorted(groups_sc.items())},
        by_motion={k: summarise(v) for k, v in sorted(groups_mo.items())},
        per_scene=per_scene,
        by_query={k: summarise(v) for k, v in sorted(groups_q.items())},
        by_relation={k: summarise(v) for k, v in sorted(groups_rel.items())},
        by_pairing={k: summarise(v) for k, v in sorted(groups_pair.items())},
        by_snr={k: summarise(groups_snr[k]) for k in SNR_GROUPS if k in groups_snr},
        blind=blind, blind_flag=blind_flag(split, overall, blind),
    )


def blind_flag(split: str, overall: dict, blind: dict) -> str:
    """One line when a blind answer scores within CLOSE_DEG of the predictions' MAE."""
    if not blind:
        return ""
    name, best = min(blind.items(), key=lambda kv: kv[1]["mae"])
    if not best["mae"] <= overall["mae"] + CLOSE_DEG:
        return ""
    return (f"warning: split {split}: answering blind ({name}) scores {best['mae']:.1f} deg against the predictions' "
            f"{overall['mae']:.1f} deg: this split rewards what a model can learn without listening")


SNR_GROUPS = ("<10dB", "10-20dB", "20-30dB", ">=30dB", "dbfs-only")


def scene_snr(noise) -> float | None:
    """A scene's SNR against all its noise (dB): its noises' SNRs combined in power (noises
    independent of each other); None when no noise has an SNR (sensor noise in dBFS)."""
    snrs = [n.snr_db for n in noise if n.snr_db is not None]
    return None if not snrs else float(-10 * np.log10(np.sum(10 ** (-np.asarray(snrs) / 10))))


def snr_group(noise) -> str:
    """The group of :data:`SNR_GROUPS` a scene with ``noise`` (its records) is scored in."""
    snr = scene_snr(noise)
    if snr is None:
        return "dbfs-only"
    return SNR_GROUPS[0] if snr < 10 else SNR_GROUPS[1] if snr < 20 else SNR_GROUPS[2] if snr < 30 else SNR_GROUPS[3]


def write_predictions(path: str, rows) -> None:
    """Write predictions ({"scene_id", "azimuth" | "distribution"} dicts) as JSONL."""
    with open(path, "w", encoding="utf-8") as f:
        for r in rows:
            r = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in r.items()}
            f.write(json.dumps(r) + "\n")

