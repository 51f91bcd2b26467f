"""Training: soft-label cross-entropy on the 360 azimuth classes, best epoch by validation MAE.

Targets are the wrapped Gaussians of :func:`tsel_data.tools.labels.gaussian_target` (σ
degrees): neighbouring classes are nearly right, which a one-hot target would not
say. A frame-level model is trained on the frames where the chosen source is active
(the frames the metric scores).

Randomness: model initialisation, dropout and batch order come from torch's generator
seeded with ``seed`` inside :func:`torch.random.fork_rng` (the caller's global state is
left as it was); augmentation from numpy generators seeded with (seed, epoch, example).
"""
from __future__ import annotations

import copy
import os
import time
from dataclasses import asdict, dataclass

import numpy as np
import torch

from tsel_data.tools.labels import gaussian_target

from .data import Examples, FeatureTable, example_list
from .model import ModelConfig, build_model, pool_frames


@dataclass
class TrainConfig:
    """epochs, batch_size, lr (peak, one-cycle schedule), weight_decay; sigma: target
    width (deg); augment: rotate/mirror examples; all_sources: every positioned source of
    a training scene is an example with its own caption (see :mod:`tsel_baseline.data`)."""

    epochs: int = 40
    batch_size: int = 32
    lr: float = 2e-3
    weight_decay: float = 1e-4
    sigma: float = 4.0
    augment: bool = True
    all_sources: bool = True
    seed: int = 0
    threads: int = 0
    activity_weight: float = 0.5  # auxiliary loss of models that say when the queried sound is on (SelectNet)

    def to_dict(self) -> dict:
        return asdict(self)


def set_threads(threads: int = 0) -> int:
    """Use ``threads`` torch threads (0: every core this process may run on)."""
    if not threads:
        threads = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    n = threads
    torch.set_num_threads(max(1, int(n)))
    return torch.get_num_threads()


def soft_cross_entropy(logits: torch.Tensor, target: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Mean over rows (where ``mask``) of ``-Σ_k target_k log softmax(logits)_k``; [..., 360] inputs."""
    loss = -(target * torch.log_softmax(logits, dim=-1)).sum(dim=-1)
    if mask is None:
        return loss.mean()
    m = mask.float()
    return (loss * m).sum() / m.sum().clamp(min=1.0)


def batch_features(batch: dict, inputs) -> dict:
    return {name: batch[f"feat_{name}"] for name in inputs}


def loss_on_batch(model, batch: dict, sigma: float, activity_weight: float = 0.0) -> torch.Tensor:
    """Soft-label cross-entropy of the azimuth, plus (for models with an ``activity``
    output) ``activity_weight`` times the binary cross-entropy of "is the queried source
    on in this frame" against the chosen source's ``active`` labels."""
    out = model.outputs(batch_features(batch, model.cfg.inputs), batch["text"])
    logits = out["logits"]
    if model.cfg.output == "clip":
        target = torch.from_numpy(gaussian_target(batch["clip_azimuth"].numpy(), sigma))
        loss = soft_cross_entropy(logits, target)
    else:
        az = batch["azimuth"].numpy()
        mask = batch["active"] & torch.from_numpy(np.isfinite(az))
        target = torch.from_numpy(gaussian_target(np.where(mask.numpy(), az, np.nan), sigma))
        loss = soft_cross_entropy(logits, target, mask)
    if activity_weight and "activity" in out:
        act = out["activity"]
        on = pool_frames(batch["active"].float(), model.cfg.pool_frames)  # share of each pooled frame
        loss = loss + activity_weight * torch.nn.functional.binary_cross_entropy_with_logits(act, on)
    return loss


def feature_norm(source, n: int = 512) -> dict:
    """(mean, std) per input from up to ``n`` training scenes.

    log-mel: per band. gcc and iv: one scalar std and no mean, so the standardised
    features still rotate exactly under :mod:`tsel_baseline.augment` (GCC-PHAT values are
    ~0.06, far below the log-mel's unit scale, and would otherwise be drowned).
    """
    if isinstance(source, FeatureTable):
        feats = {k: v[:n] for k, v in source.features.items()}
    else:
        items = [source[i]["features"] for i in range(min(len(source), n))]
        feats = {k: np.stack([it[k] for it in items]) for k in items[0]}
    out = {}
    for name, x in feats.items():
        if name == "mel":
            flat = x.reshape(-1, x.shape[-1])
            out[name] = (flat.mean(axis=0), flat.std(axis=0) + 1e-3)
        else:
            out[name] = (np.float32(0.0), np.float32(np.sqrt((x.astype(np.float64) ** 2).mean()) + 1e-6))
    return out


def fit(model_cfg: ModelConfig, cfg: TrainConfig, train_source, text, validate=None, log=print):
    """Train the network of ``model_cfg`` (:func:`tsel_baseline.model.build_model`); returns ``(model, history)``.

    train_source: a :class:`FeatureTable` or :class:`SceneFeatures` of the training split.
    text:         callable list[str] -> float32 [N, D] (a fitted text encoder's ``encode``).
    validate:     optional callable model -> validation MAE (deg); the epoch with the lowest
                  is kept. Without it, the last epoch is kept.
    """
    log = log or (lambda msg: None)
    set_threads(cfg.threads)
    examples = example_list(train_source, cfg.all_sources)
    data = Examples(train_source, examples, text, augment=cfg.augment, seed=cfg.seed)
    first = data[0]
    shapes = {k[5:]: v.shape for k, v in first.items() if k.startswith("feat_")}
    norm = feature_norm(train_source)
    history, best, best_state = [], float("inf"), None
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(cfg.seed)
        model = build_model(model_cfg, shapes, first["text"].shape[0], norm)
        opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        loader = torch.utils.data.DataLoader(data, batch_size=cfg.batch_size, shuffle=True, drop_last=True,
                                             generator=torch.Generator().manual_seed(cfg.seed))
        sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=cfg.epochs * len(loader),
                                                    pct_start=0.15)
        log(f"  training on {len(examples)} examples from {len(train_source)} scenes, "
            f"{sum(p.numel() for p in model.parameters()) / 1e6:.2f} M parameters, {cfg.epochs} epochs")
        for epoch in range(cfg.epochs):
            t0 = time.time()
            data.set_epoch(epoch)
            model.train()
            total, n = 0.0, 0
            for batch in loader:
                loss = loss_on_batch(model, batch, cfg.sigma, cfg.activity_weight)
                opt.zero_grad()
                loss.backward()
                opt.step()
                sched.step()
                total, n = total + loss.item(), n + 1
            row = {"epoch": epoch + 1, "loss": total / max(n, 1), "seconds": time.time() - t0}
            if validate is not None:
                row["val_mae"] = float(validate(model))
                if row["val_mae"] < best:
                    best, best_state = row["val_mae"], copy.deepcopy(model.state_dict())
            history.append(row)
            log("  epoch {epoch:3d}  loss {loss:.3f}  {seconds:.1f} s".format(**row)
                + (f"  val MAE {row['val_mae']:.2f}°" if "val_mae" in row else ""))
        if best_state is not None:
            model.load_state_dict(best_state)
    model.eval()
    return model, history
