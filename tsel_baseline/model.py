"""The baseline network: audio frames + a caption vector -> azimuth distribution(s).

::

    gcc [P, F, L] ─ per-frame MLP ─┐
    iv  [3, F, M] ─ per-frame MLP ─┼─ concat ─ temporal convs ─ h [F, H]
    mel [F, M]    ─ per-frame MLP ─┘                             │
    text vector [D] ─ MLP ─ t [T] ───────────────────────────────┤
                                                                 ├─ clip:  [mean_F h, max_F h, t] ─ MLP ─ 360 logits
                                                                 └─ frame: [h_f, t] per frame ─ conv over frames ─ 360 logits per frame

The clip head is the paper's best fusion (concatenate clip-level audio and text
embeddings); the frame head gives one distribution per label frame for moving targets.
Frame MLPs rather than 2-D convolutions over the lag axis: a lag has an absolute
meaning (a delay between two given mics), and the per-frame MLP costs a fraction of a
convolution on 2 CPU cores. Bin k of the output is azimuth k degrees (the paper's 360
classes, tsel_data.tools.labels).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

N_CLASSES = 360


@dataclass
class ModelConfig:
    """inputs: feature names the model reads ("gcc", "iv", "mel"); output: "clip" or "frame";
    hidden: width H of frame embeddings; text_dim: width T of the text embedding."""

    inputs: tuple = ("gcc",)
    output: str = "clip"
    hidden: int = 128
    text_dim: int = 128
    dropout: float = 0.1
    temporal_layers: int = 3
    pool_frames: int = 1  # average this many label frames into one before anything else (clip head only)
    fusion: str = "concat"  # "concat": the paper's clip-level concatenation (TselNet); "select": SelectNet

    def to_dict(self) -> dict:
        d = asdict(self)
        d["inputs"] = list(self.inputs)
        return d


def _mlp(d_in: int, d_hidden: int, d_out: int, dropout: float) -> nn.Sequential:
    return nn.Sequential(nn.Linear(d_in, d_hidden), nn.ReLU(), nn.Dropout(dropout), nn.Linear(d_hidden, d_out))


class TemporalBlock(nn.Module):
    """Residual dilated 1-D convolution over frames: [B, H, F] -> [B, H, F]."""

    def __init__(self, h: int, dilation: int, dropout: float):
        super().__init__()
        self.conv = nn.Conv1d(h, h, kernel_size=3, padding=dilation, dilation=dilation)
        self.norm = nn.BatchNorm1d(h)
        self.drop = nn.Dropout(dropout)

    def forward(self, x):
        return x + self.drop(torch.relu(self.norm(self.conv(x))))


class TselNet(nn.Module):
    """See the module docstring. ``shapes``: per input, one scene's feature shape;
    ``norm``: per input, (mean, std) broadcastable to its last axis (from :func:`feature_norm`)."""

    def __init__(self, cfg: ModelConfig, shapes: dict, text_in: int, norm: dict | None = None):
        super().__init__()
        self.cfg = cfg
        h = cfg.hidden
        self.branches = nn.ModuleDict()
        norm = norm or {}
        for name in cfg.inputs:
            if name not in shapes:
                raise ValueError(f"the model reads {name!r} features but the data has {sorted(shapes)}")
            self.branches[name] = _mlp(self._frame_dim(name, shapes[name]), h, h, cfg.dropout)
            mean, std = norm.get(name, (0.0, 1.0))
            # buffers, so a saved model carries the training data's scale with it
            self.register_buffer(f"{name}_mean", torch.as_tensor(mean, dtype=torch.float32))
            self.register_buffer(f"{name}_std", torch.as_tensor(std, dtype=torch.float32))
        self.merge = nn.Linear(h * len(cfg.inputs), h)
        self.temporal = nn.Sequential(*[TemporalBlock(h, 2 ** i, cfg.dropout) for i in range(cfg.temporal_layers)])
        self.text = _mlp(text_in, cfg.text_dim, cfg.text_dim, cfg.dropout)
        if cfg.output == "clip":
            self.head = _mlp(2 * h + cfg.text_dim, h, N_CLASSES, cfg.dropout)
        elif cfg.output == "frame":
            # a convolution over frames, not a GRU: as good a smoother here and ~10x faster on CPU
            self.head = nn.Sequential(nn.Conv1d(h + cfg.text_dim, h, kernel_size=5, padding=2), nn.ReLU(),
                                      nn.Dropout(cfg.dropout), nn.Conv1d(h, N_CLASSES, kernel_size=1))
        else:
            raise ValueError(f"output must be 'clip' or 'frame', got {cfg.output!r}")
        if cfg.output == "frame" and cfg.pool_frames != 1:
            raise ValueError("a frame-level head predicts every label frame: pool_frames must be 1")

    @staticmethod
    def _frame_dim(name: str, shape) -> int:
        # gcc [P, F, L], xspec [P, F, M, 2] and iv [3, F, M] keep frames on axis 1; mel [F, M] on axis 0
        return int(np.prod(shape)) // (shape[0] if name == "mel" else shape[1])

    def _frames(self, name: str, x: torch.Tensor) -> torch.Tensor:
        """One input [B, ...] -> standardised [B, F, d]."""
        x = (x - getattr(self, f"{name}_mean")) / getattr(self, f"{name}_std")
        x = x if name == "mel" else x.transpose(1, 2).flatten(2)  # [B, C, F, L] -> [B, F, C·L]
        k = self.cfg.pool_frames
        # a static target needs no 100 ms detail: pooling frames halves the cost per k = 2
        return x if k == 1 else nn.functional.avg_pool1d(x.transpose(1, 2), k, ceil_mode=True).transpose(1, 2)

    def audio_frames(self, feats: dict) -> torch.Tensor:
        """Frame embeddings h: {name: [B, ...]} -> [B, F, H]."""
        parts = [self.branches[n](self._frames(n, feats[n])) for n in self.cfg.inputs]
        x = torch.relu(self.merge(torch.cat(parts, dim=-1)))
        return self.temporal(x.transpose(1, 2)).transpose(1, 2)

    def outputs(self, feats: dict, text: torch.Tensor) -> dict:
        return {"logits": self(feats, text)}

    def forward(self, feats: dict, text: torch.Tensor) -> torch.Tensor:
        """Logits: [B, 360] (clip) or [B, F, 360] (frame)."""
        h = self.audio_frames(feats)
        t = torch.relu(self.text(text))
        if self.cfg.output == "clip":
            pooled = torch.cat([h.mean(dim=1), h.amax(dim=1)], dim=-1)
            return self.head(torch.cat([pooled, t], dim=-1))
        z = torch.cat([h, t[:, None].expand(-1, h.shape[1], -1)], dim=-1)
        return self.head(z.transpose(1, 2)).transpose(1, 2)


def pool_frames(x: torch.Tensor, k: int) -> torch.Tensor:
    """Average every ``k`` frames: [N, F, ...] -> [N, ceil(F / k), ...] (the last group may be shorter)."""
    if k == 1:
        return x
    f = x.shape[1]
    pad = -f % k
    if pad:  # repeat the last frame, so the last group's mean is that of its real frames
        x = torch.cat([x, x[:, -1:].expand(-1, pad, *x.shape[2:])], dim=1)
    return x.reshape(x.shape[0], -1, k, *x.shape[2:]).mean(dim=2)


class SelectNet(nn.Module):
    """The text chooses *which frames and bands* to localise, before anything is pooled.

    ::

        mel   [F, M]        ─┐
        xspec [P, F, B, 2]  ─┴─ per-frame MLP ─ FiLM(text) ─ temporal convs ─ h [F, H]
        text vector ─ MLP ─ t ──────┘                                           │
                                         mask  w[f, b] = sigmoid(Linear(h_f))  ─┤   activity(f) = Linear(h_f)
        clip:  Σ_f w[f, b] · xspec[:, f, b]  per band ─ MLP ─ 360 logits         │   (auxiliary: is the queried
        frame: w[f, b] · xspec[:, f, b]  per frame ─ conv over frames ─ 360 per frame   sound on in frame f?)

    The text modulates every frame embedding (FiLM: ``h·(1 + γ(t)) + β(t)``) *before*
    the temporal layers, so "what sounds when" is matched to the query frame by frame.
    The mask then picks time-frequency cells of the spatial feature, and only the
    picked cells reach the direction head: a band's phase is the direction of what
    dominates that band, so picking the bands of the queried sound picks its direction.
    The spatial feature is ``xspec`` (mic arrays, see :func:`tsel_baseline.features.xspec_features`)
    or ``iv`` (FOA intensity vectors per band); ``mel`` is optional but the point.
    """

    SPATIAL = ("xspec", "iv")

    def __init__(self, cfg: ModelConfig, shapes: dict, text_in: int, norm: dict | None = None):
        super().__init__()
        self.cfg = cfg
        h, norm = cfg.hidden, norm or {}
        spatial = [n for n in cfg.inputs if n in self.SPATIAL]
        if len(spatial) != 1 or any(n not in (*self.SPATIAL, "mel") for n in cfg.inputs):
            raise ValueError(f"fusion 'select' reads one of {self.SPATIAL} (and 'mel'), got {list(cfg.inputs)}")
        self.spatial = spatial[0]
        for name in cfg.inputs:
            if name not in shapes:
                raise ValueError(f"the model reads {name!r} features but the data has {sorted(shapes)}")
            mean, std = norm.get(name, (0.0, 1.0))
            self.register_buffer(f"{name}_mean", torch.as_tensor(mean, dtype=torch.float32))
            self.register_buffer(f"{name}_std", torch.as_tensor(std, dtype=torch.float32))
        shape = shapes[self.spatial]
        # xspec [P, F, B, 2] -> B bands of P·2 numbers; iv [3, F, M] -> M bands of 3
        self.n_bands = shape[2]
        self.band_dim = shape[0] * shape[3] if self.spatial == "xspec" else shape[0]
        d_in = self.n_bands * self.band_dim + (shapes["mel"][1] if "mel" in cfg.inputs else 0)
        self.frame = _mlp(d_in, h, h, cfg.dropout)
        self.text = _mlp(text_in, cfg.text_dim, cfg.text_dim, cfg.dropout)
        self.film = nn.Linear(cfg.text_dim, 2 * h)
        self.temporal = nn.Sequential(*[TemporalBlock(h, 2 ** i, cfg.dropout) for i in range(cfg.temporal_layers)])
        self.mask = nn.Linear(h, self.n_bands)
        self.activity = nn.Linear(h, 1)
        d_sel = self.n_bands * (self.band_dim + 1)
        if cfg.output == "frame" and cfg.pool_frames != 1:
            raise ValueError("a frame-level head predicts every label frame: pool_frames must be 1")
        if cfg.output == "clip":
            self.head = nn.Sequential(nn.Linear(d_sel, 2 * h), nn.ReLU(), nn.Dropout(cfg.dropout),
                                      nn.Linear(2 * h, 2 * h), nn.ReLU(), nn.Linear(2 * h, N_CLASSES))
        elif cfg.output == "frame":
            self.head = nn.Sequential(nn.Conv1d(d_sel + h, 2 * h, kernel_size=5, padding=2), nn.ReLU(),
                                      nn.Dropout(cfg.dropout), nn.Conv1d(2 * h, N_CLASSES, kernel_size=1))
        else:
            raise ValueError(f"output must be 'clip' or 'frame', got {cfg.output!r}")

    def bands(self, x: torch.Tensor) -> torch.Tensor:
        """The spatial input [N, ...] -> [N, F, bands, band_dim], unscaled (xspec lies in the unit disc)."""
        if self.spatial == "xspec":
            return x.permute(0, 2, 3, 1, 4).flatten(3)          # [N, P, F, B, 2] -> [N, F, B, P·2]
        return x.permute(0, 2, 3, 1)                            # [N, 3, F, M] -> [N, F, M, 3]

    def outputs(self, feats: dict, text: torch.Tensor) -> dict:
        """``logits`` [N, 360] or [N, F, 360], ``activity`` logits [N, F], ``mask`` [N, F, bands]."""
        s = pool_frames(self.bands(feats[self.spatial]), self.cfg.pool_frames)
        x = [(s / getattr(self, f"{self.spatial}_std")).flatten(2)]
        if "mel" in self.cfg.inputs:
            x.append(pool_frames((feats["mel"] - self.mel_mean) / self.mel_std, self.cfg.pool_frames))
        t = torch.relu(self.text(text))
        gamma, beta = self.film(t)[:, None].chunk(2, dim=-1)
        hf = self.frame(torch.cat(x, dim=-1))                   # [N, F, H]
        hf = torch.relu(hf * (1 + gamma) + beta)
        hf = self.temporal(hf.transpose(1, 2)).transpose(1, 2)
        w = torch.sigmoid(self.mask(hf))                        # [N, F, B]
        picked = w[..., None] * s                               # [N, F, B, band_dim]
        if self.cfg.output == "clip":
            norm = w.sum(dim=(1, 2))[:, None] / self.n_bands + 1e-3
            sel = torch.cat([picked.sum(dim=1).flatten(1), w.sum(dim=1)], dim=-1) / norm   # [N, B·(band_dim + 1)]
            logits = self.head(sel)
        else:
            z = torch.cat([picked.flatten(2), w, hf], dim=-1)   # [N, F, ...]
            logits = self.head(z.transpose(1, 2)).transpose(1, 2)
        return {"logits": logits, "activity": self.activity(hf)[..., 0], "mask": w}

    def forward(self, feats: dict, text: torch.Tensor) -> torch.Tensor:
        return self.outputs(feats, text)["logits"]


def build_model(cfg: ModelConfig, shapes: dict, text_in: int, norm: dict | None = None) -> nn.Module:
    """The network of ``cfg.fusion``: "concat" (:class:`TselNet`, the paper's) or "select" (:class:`SelectNet`)."""
    if cfg.fusion == "concat":
        return TselNet(cfg, shapes, text_in, norm)
    if cfg.fusion == "select":
        return SelectNet(cfg, shapes, text_in, norm)
    raise ValueError(f"fusion must be 'concat' or 'select', got {cfg.fusion!r}")


def decode(logits: torch.Tensor, width: int = 3) -> np.ndarray:
    """Azimuth (deg, [-180, 180)) from logits [..., 360]: the circular centroid of the
    softmax over the argmax bin ± ``width`` bins (sub-degree, unlike a bare argmax)."""
    p = torch.softmax(logits.float(), dim=-1)
    k = p.argmax(dim=-1, keepdim=True)
    offs = torch.arange(-width, width + 1)
    idx = (k + offs) % N_CLASSES
    w = torch.gather(p, -1, idx)
    ang = torch.deg2rad((k + offs).float())
    az = torch.rad2deg(torch.atan2((w * torch.sin(ang)).sum(-1), (w * torch.cos(ang)).sum(-1)))
    return (((az + 180.0) % 360.0) - 180.0).numpy()
