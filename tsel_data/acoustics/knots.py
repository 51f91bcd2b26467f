"""The image-source parts of a moving source's knots, all knots at once.

A moving source is simulated at a hundred or more knots (placement.knot_hop), each one
image set as the shoebox simulator sees it (shoebox.py, image groups: image_paths.py).
Knot by knot, that was some twenty Python-level calls per knot and group and channel,
most of a moving scene's simulation time. Here the images come from their grouping
(where every image is at every knot, already computed to group them), every image's delay
and weight at every channel of every knot from the capsule model in one call per batch
of knots (``model.impulses``), and every tap of every impulse goes to its row (knot,
group, channel) of the output in one ``bincount``: the fractional-delay interpolator of
ism.py, the same sum a grid renders (tap by tap), within float64 rounding.

The DC blocker is not applied here: it is one linear filter, the same for every knot, so
it commutes with the time-varying render and is applied once to what is rendered from
these parts (render.path_image), not to every knot's RIR.
"""
from __future__ import annotations

import numpy as np

from .ism import FD_TAPS, _fd_bank, _split

BATCH = 1 << 13  # impulses placed per bincount: its temporaries (taps [M, 32]) stay in cache


def batched(model) -> bool:
    """Whether the capsule model gives its impulses for many images at once (spaced
    capsules and ambisonics, and channels mixed from those); others go knot by knot."""
    base = getattr(model, "base", model)
    return hasattr(base, "impulses")


def knot_parts(model, grouped, centre, radius: float, a: float, fade, n_img: int) -> np.ndarray:
    """The knots' image parts, float32 [K, G·C, n_img] (group-major, as shoebox.py returns
    them): images within ``radius`` of ``centre`` at each knot, each with β^order, β =
    exp(-a), faded by ``fade``, through ``model``'s capsules; ``grouped``: the
    :class:`~tsel_data.acoustics.image_paths.ImageGroups` of the knots (its orders and
    positions)."""
    base = getattr(model, "base", model)
    matrix = getattr(model, "matrix", None)
    pos, group, G = grouped.positions, grouped.group, grouped.n_groups
    N, K = pos.shape[:2]
    Cb, C = base.n_channels, model.n_channels
    amp = np.exp(-a * np.asarray(grouped.orders, dtype=np.float64))
    d = pos - np.asarray(centre, dtype=np.float64)
    inside = np.einsum("nkx,nkx->nk", d, d) <= radius * radius  # [N, K]
    per_knot = inside.sum(axis=0) * Cb
    out = np.empty((K, G * C, n_img), dtype=np.float32)
    k0 = 0
    while k0 < K:
        k1 = k0 + max(1, int(np.searchsorted(np.cumsum(per_knot[k0:]), BATCH, side="right")))
        k, n = np.nonzero(inside[:, k0:k1].T)  # knot by knot: each bincount writes a few rows
        delays, weights = base.impulses(pos[n, k0 + k], amp[n], fade)  # [M, Cb]
        rows = (k[:, None] * G + group[n][:, None]) * Cb + np.arange(Cb)[None, :]
        placed = place(delays.ravel(), weights.ravel(), rows.ravel(), (k1 - k0) * G * Cb, n_img)
        placed = placed.reshape(k1 - k0, G, Cb, n_img)
        if matrix is not None:
            placed = np.einsum("cb,kgbn->kgcn", matrix, placed)
        out[k0:k1] = placed.reshape(k1 - k0, G * C, n_img)
        k0 = k1
    return out


def place(d: np.ndarray, w: np.ndarray, rows: np.ndarray, n_rows: int, length: int) -> np.ndarray:
    """float64 [n_rows, length]: impulse i (weight w_i at fractional delay d_i samples)
    through the interpolator into row rows_i, as ism's grid places it tap by tap (delays
    at or past ``length`` are dropped, taps outside the row cut: each row is placed with a
    margin of FD_TAPS either side, then trimmed, which spares masking every tap)."""
    keep = d < length
    d, w, rows = d[keep], w[keep], rows[keep]
    first = FD_TAPS // 2 - 1
    n0, p0, frac = _split(d)
    bank = _fd_bank()
    taps = bank[p0] * (w * (1.0 - frac))[:, None]
    taps += bank[p0 + 1] * (w * frac)[:, None]
    width = length + 2 * FD_TAPS
    at = (n0 + rows * width + (FD_TAPS - first))[:, None] + np.arange(FD_TAPS)
    out = np.bincount(at.ravel(), taps.ravel(), minlength=n_rows * width).reshape(n_rows, width)
    return out[:, FD_TAPS:FD_TAPS + length]
