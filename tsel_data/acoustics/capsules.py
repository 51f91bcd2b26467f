"""How a receiver's channels hear image sources and a diffuse field: one class per capsule
model (receivers/spec.py), chosen by :func:`capsule_model` from the receiver's spec.

A model turns image sources (room-frame positions, amplitudes before spreading) into
impulses on its channels, renders them to signals, and draws diffuse noise with the
receiver's diffuse-field statistics for the late tail. The simulators call nothing else,
so a receiver of an existing model needs no code here.

- :class:`Spaced`: capsules at their own positions; each image reaches capsule c after
  r_c / c with amplitude g_c / (4π r_c), g_c = α_c + (1 - α_c) u_c·o_c the capsule's
  first-order pattern towards the image (1 for omnis).
- :class:`Ambisonic`: W, Y, Z, X (ACN/SN3D) at the centre, gains 1, u_y, u_z, u_x.
- :class:`RigidSphere`: capsules on a rigid sphere; each image reaches capsule c through
  the sphere's scattering at the angle θ_c between the capsule's normal and the image
  (acoustics/sphere.py), tabulated every degree and composed with the fractional delay.
- :class:`Binaural`: two ears; each image through the HRIR of its direction in the head
  frame (acoustics/hrtf.py: the nearest measurement or the measured triangle around it).
- :class:`Mixed`: another model's channels mixed by a matrix (DCASE stereo from FOA).

Each model's ``diffuse_csd(freqs)`` [F, C, C] is its channels' cross-spectral density in
an isotropic diffuse field of unit pressure PSD (the theory the late tail and diffuse
noise are drawn from; the omni and FOA tails keep their own closed-form generators).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..choices import Baffle, ReceiverModel
from ..core.geometry import SOUND_SPEED, array_to_room, foa_gains_of
from ..dsp import realfft as sfft  # scipy.fft's numbers without its import
from ..receivers import ArrayPose
from .ism import FD_TAPS, _split, add_impulses, fd_bank, grid_to_signal, new_grid
from .late import FOA_DIFFUSE_GAINS, csd_noise, diffuse_coherence
from .late import diffuse_noise


def fade_out(t: np.ndarray, fade) -> np.ndarray | float:
    """Power-complementary cross-fade: images get cos, the tail sin, of π/2 · ρ(t)."""
    if fade is None:
        return 1.0
    t_mix, width = fade
    rho = np.clip((t - (t_mix - width / 2)) / width, 0.0, 1.0)
    return np.cos(0.5 * np.pi * rho)


class Spaced:
    """Free-field capsules at the array's channel positions, omni or first order."""

    coincident = False

    def __init__(self, array, fs: int):
        self.fs = fs
        caps = array.spec.capsules(array)
        self.centre = np.asarray(array.centre, dtype=np.float64)
        self.mics = array_to_room(caps.positions, self.centre, array.yaw)  # [C, 3], room frame
        self.n_channels = len(self.mics)
        self.omni = caps.omni
        self.alpha = caps.alpha
        # capsule axes in the room frame (rotation only)
        self.axes = array_to_room(caps.orientation, (0.0, 0.0, 0.0), array.yaw)
        self.points = self.mics  # where the receiver is (checks, the image radius)
        self.reference = self.mics[0]  # the ISM fit's receiver (ism method)

    def new_grid(self, n: int):
        return new_grid(self.n_channels, n)

    def add(self, grid, pos: np.ndarray, amp: np.ndarray, fade) -> None:
        c = SOUND_SPEED
        for ch, m in enumerate(self.mics):
            r = np.linalg.norm(pos - m, axis=1)
            t = r / c
            w = amp / (4 * np.pi * r)
            if not self.omni and self.alpha[ch] != 1.0:
                u = (pos - m) / r[:, None]  # towards the image: where the wave comes from
                w = w * (self.alpha[ch] + (1.0 - self.alpha[ch]) * (u @ self.axes[ch]))
            add_impulses(grid, ch, t * self.fs, w * fade_out(t, fade))

    def impulses(self, pos: np.ndarray, amp: np.ndarray, fade) -> tuple[np.ndarray, np.ndarray]:
        """What :meth:`add` gives each channel, for many images at once: delays (samples)
        and weights, [N, C] each (acoustics/knots.py places them)."""
        diff = pos[:, None, :] - self.mics[None]  # [N, C, 3]
        r = np.sqrt(np.einsum("ncx,ncx->nc", diff, diff))
        t = r / SOUND_SPEED
        w = amp[:, None] / (4 * np.pi * r)
        if not self.omni and np.any(self.alpha != 1.0):
            w = w * (self.alpha + (1.0 - self.alpha) * np.einsum("ncx,cx->nc", diff, self.axes) / r)
        return t * self.fs, w * fade_out(t, fade)

    def render(self, grid) -> np.ndarray:
        return grid_to_signal(grid)

    def diffuse_noise(self, rng, n_sets: int, n: int) -> np.ndarray:
        """[n_sets, C, n] noise with the receiver's diffuse-field statistics (omni variance 1)."""
        if self.omni:
            return diffuse_noise(rng, n_sets, n, self.fs, positions=self.mics)
        return csd_noise(rng, n_sets, n, self.fs, self.diffuse_csd)

    def diffuse_csd(self, freqs) -> np.ndarray:
        """Φ_ij(f) of first-order capsules g = α + (1 - α) u·o at p_i, p_j in a diffuse
        field (G. W. Elko, "Spatial coherence functions for differential microphones in
        isotropic noise fields", in Brandstein & Ward (eds.), Microphone Arrays, 2001):
        with x = k d, e = (p_i - p_j) / d and the package's delay convention,

            Φ_ij = α_i α_j j0(x) + i j1(x) [α_i (1-α_j) o_j·e + α_j (1-α_i) o_i·e]
                   + (1-α_i)(1-α_j) [o_i·o_j j1(x)/x - (o_i·e)(o_j·e) j2(x)],

        Φ_ii = α_i² + (1-α_i)²/3; omnis: sinc(kd)."""
        return spaced_csd(freqs, self.mics, self.alpha, self.axes)


class Ambisonic:
    """First-order ambisonics (ACN/SN3D) at the array centre."""

    coincident = True
    n_channels = 4

    def __init__(self, array, fs: int):
        self.fs = fs
        self.centre = np.asarray(array.centre, dtype=np.float64)
        self.yaw = array.yaw
        self.points = self.centre[None, :]
        self.reference = self.centre

    def new_grid(self, n: int):
        return new_grid(4, n)

    def add(self, grid, pos: np.ndarray, amp: np.ndarray, fade) -> None:
        """Gains 1, u_y, u_z, u_x of the unit direction u in the array frame
        (geometry.foa_gains_of, the convention of docs/format.md)."""
        v = pos - self.centre
        r = np.linalg.norm(v, axis=1)
        c, s = np.cos(np.radians(self.yaw)), np.sin(np.radians(self.yaw))
        ux = (c * v[:, 0] + s * v[:, 1]) / r  # Rz(-yaw) v
        uy = (-s * v[:, 0] + c * v[:, 1]) / r
        uz = v[:, 2] / r
        gains = foa_gains_of(np.stack([ux, uy, uz], axis=-1))  # [N, 4]
        t = r / SOUND_SPEED
        w = amp / (4 * np.pi * r) * fade_out(t, fade)
        for ch in range(4):
            add_impulses(grid, ch, t * self.fs, w if ch == 0 else w * gains[:, ch])

    def impulses(self, pos: np.ndarray, amp: np.ndarray, fade) -> tuple[np.ndarray, np.ndarray]:
        """What :meth:`add` gives W, Y, Z, X for many images at once: delays (samples) and
        weights, [N, 4] each."""
        v = pos - self.centre
        r = np.sqrt(np.einsum("nx,nx->n", v, v))
        c, s = np.cos(np.radians(self.yaw)), np.sin(np.radians(self.yaw))
        u = np.stack([(c * v[:, 0] + s * v[:, 1]) / r, (-s * v[:, 0] + c * v[:, 1]) / r, v[:, 2] / r], axis=-1)
        gains = foa_gains_of(u)
        t = r / SOUND_SPEED
        w = (amp / (4 * np.pi * r) * fade_out(t, fade))[:, None] * gains
        return np.repeat((t * self.fs)[:, None], 4, axis=1), w

    def render(self, grid) -> np.ndarray:
        return grid_to_signal(grid)

    def diffuse_noise(self, rng, n_sets: int, n: int) -> np.ndarray:
        return diffuse_noise(rng, n_sets, n, self.fs, foa=True)

    def diffuse_csd(self, freqs) -> np.ndarray:
        """Uncorrelated W, Y, Z, X with energies 1 : 1/3 : 1/3 : 1/3 (the mean of u_i² over the sphere)."""
        return np.broadcast_to(np.diag(FOA_DIFFUSE_GAINS ** 2), (len(np.atleast_1d(freqs)), 4, 4)).copy()


class Mixed:
    """Channels mixed from a base receiver's by ``matrix`` [C, C_base] (the spec's
    ``base`` and ``matrix``): whatever the base hears, mixed."""

    def __init__(self, array, fs: int):
        spec = array.spec
        base = ArrayPose(spec.base, array.centre, array.yaw)
        self.base = capsule_model(base, fs)
        self.matrix = np.asarray(spec.matrix, dtype=np.float64)
        self.n_channels = len(self.matrix)
        self.coincident = self.base.coincident
        self.points, self.reference = self.base.points, self.base.reference
        self.fs = fs

    def new_grid(self, n: int):
        return self.base.new_grid(n)

    def add(self, grid, pos, amp, fade) -> None:
        self.base.add(grid, pos, amp, fade)

    def render(self, grid) -> np.ndarray:
        return self.matrix @ self.base.render(grid)

    def diffuse_noise(self, rng, n_sets: int, n: int) -> np.ndarray:
        return np.einsum("cb,sbn->scn", self.matrix, self.base.diffuse_noise(rng, n_sets, n))

    def diffuse_csd(self, freqs) -> np.ndarray:
        return np.einsum("cb,fbd,ed->fce", self.matrix, self.base.diffuse_csd(freqs), self.matrix)


class RigidSphere:
    """Capsules on a rigid sphere of the spec's radius (the DCASE MIC format, an Eigenmike).

    Image i, arriving at the centre after t_i = r_i / c, reaches capsule c through the
    sphere's response to a point source at r_i, H(f, r_i, θ_ic) (acoustics/sphere.py,
    Duda & Martens' range dependence), θ_ic between the capsule's outward normal and the
    direction of the image, scaled by 1 / (4π r_i): each image is a kernel of the response
    tabulated every degree, already convolved with the fractional-delay interpolator at its
    FD_PHASES + 1 phases, interpolated linearly in angle and phase and placed tap by tap.
    The range is tabulated at :data:`SPHERE_RANGES` and interpolated linearly in 1/r
    between the two around r_i (within 0.05 dB and 0.25° of the series from 0.25 m, 0.01
    dB and 0.05° beyond 1 m); images at least :data:`PLANE_WAVE_RANGE` away are plane
    waves (0.04 dB, 0.7° at 16 m). Treating every image as a plane wave was 0.64 dB and
    11° off at 1 m, 0.26 dB and 4° at 2.5 m. The late tail has the sphere's diffuse
    cross-spectra (:func:`~tsel_data.acoustics.sphere.rigid_sphere_diffuse`).
    """

    coincident = False

    def __init__(self, array, fs: int):
        spec = array.spec
        self.fs, self.radius = fs, spec.radius
        pos = spec.positions(array)
        self.centre = np.asarray(array.centre, dtype=np.float64)
        self.mics = array_to_room(pos, self.centre, array.yaw)
        self.normals = array_to_room(pos / np.linalg.norm(pos, axis=1, keepdims=True), (0.0, 0.0, 0.0), array.yaw)
        self.n_channels = len(pos)
        self.points = self.mics
        self.reference = self.mics[0]
    def new_grid(self, n: int):
        return _AngleGrid(self.n_channels, n)

    def add(self, grid, pos: np.ndarray, amp: np.ndarray, fade) -> None:
        v = pos - self.centre
        r = np.linalg.norm(v, axis=1)
        t = r / SOUND_SPEED
        w = amp / (4 * np.pi * r) * fade_out(t, fade)
        cos = (v / r[:, None]) @ self.normals.T  # [N, C]
        # each near image split between the two tabulated ranges around it (linear in 1/r)
        near = np.flatnonzero(r < PLANE_WAVE_RANGE)
        inv = 1.0 / r[near]
        k = np.clip(np.searchsorted(_INVERSE_RANGES, inv, side="right") - 1, 0, len(_INVERSE_RANGES) - 2)
        up = np.clip((inv - _INVERSE_RANGES[k]) / (_INVERSE_RANGES[k + 1] - _INVERSE_RANGES[k]), 0.0, 1.0)
        bins = np.zeros(len(r), dtype=np.int64)
        bins[near] = k
        weights = w.copy()
        weights[near] = w[near] * (1.0 - up)
        for ch in range(self.n_channels):
            grid.add(ch, t * self.fs, weights, cos[:, ch], bins)
            grid.add(ch, t[near] * self.fs, w[near] * up, cos[near, ch], k + 1)

    def render(self, grid) -> np.ndarray:
        out = np.zeros((self.n_channels, grid.length))
        for ch in range(self.n_channels):
            d, w, cos, bins = grid.channel(ch)
            for b in np.unique(bins):
                sel = bins == b
                table, offset = _sphere_kernels(int(self.fs), float(self.radius), SPHERE_RANGES[b])
                out[ch] += _place_kernels(d[sel], w[sel], cos[sel], table, offset, grid.length)
        return out

    def diffuse_noise(self, rng, n_sets: int, n: int) -> np.ndarray:
        return csd_noise(rng, n_sets, n, self.fs, self.diffuse_csd)

    def diffuse_csd(self, freqs) -> np.ndarray:
        """Φ_ij(f) = Σ_n (2n+1) |b_n(kR)|² P_n(cos γ_ij), γ_ij the angle between the capsules."""
        nrm = self.normals
        cos = np.clip(nrm @ nrm.T, -1.0, 1.0)
        vals, inv = np.unique(np.round(cos, 12), return_inverse=True)
        from .sphere import rigid_sphere_diffuse  # (see _sphere_kernels)

        phi = rigid_sphere_diffuse(np.atleast_1d(freqs), self.radius, vals)  # [F, G]
        return phi[:, inv.reshape(cos.shape)]


class _AngleGrid:
    """Impulses per channel with the cosine of the angle each arrives at and the index of
    its tabulated range (:data:`SPHERE_RANGES`)."""

    __slots__ = ("length", "parts")

    def __init__(self, n_ch: int, length: int):
        self.length = int(length)
        self.parts: list[list[tuple]] = [[] for _ in range(n_ch)]

    def add(self, ch: int, delays, weights, cos, bins) -> None:
        keep = delays < self.length
        self.parts[ch].append((delays[keep], weights[keep], cos[keep], bins[keep]))

    def channel(self, ch: int):
        if not self.parts[ch]:
            return np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64)
        return tuple(np.concatenate(x) for x in zip(*self.parts[ch]))


_CHUNK = 8192  # images per kernel batch: [chunk, taps] stays a few MB

# Ranges (m) at which the point-source response is tabulated, nearest last (None: a plane
# wave); images nearer than the last use it. Linear in 1/r between them (see RigidSphere).
SPHERE_RANGES = (None, 8.0, 4.0, 2.0, 1.0, 0.7, 0.5, 0.35, 0.25)
_INVERSE_RANGES = np.array([0.0 if r is None else 1.0 / r for r in SPHERE_RANGES])
PLANE_WAVE_RANGE = 16.0  # m: images this far or farther are plane waves


@lru_cache(maxsize=2 * len(SPHERE_RANGES))
def _sphere_kernels(fs: int, radius: float, distance: float | None = None) -> tuple[np.ndarray, int]:
    """The rigid sphere's responses every degree (to a plane wave, or to a point source
    ``distance`` m away), each convolved with the interpolator at its FD_PHASES + 1 phases:
    [181, FD_PHASES + 1, L] float64, and the offset (samples) of tap 0 from an impulse's
    integer delay (the response's lead and the interpolator's), the same at every range."""
    # scipy.special and the modal series: only sphere receivers pay for their import
    from .sphere import rigid_sphere_filters

    if distance is not None and distance <= radius:
        distance = None  # a sphere larger than a range: never reached (images lie outside it)
    filt = rigid_sphere_filters(fs, radius, distance=distance)
    rows, bank = filt.table, fd_bank()  # [A, S], [P, K]
    n = rows.shape[1] + bank.shape[1] - 1
    n_fft = sfft.next_fast_len(n, real=True)
    spec = sfft.rfft(rows, n_fft)[:, None, :] * sfft.rfft(bank, n_fft)[None, :, :]
    table = sfft.irfft(spec, n_fft)[..., :n]
    table.setflags(write=False)
    return table, -(filt.lead + FD_TAPS // 2 - 1)


def _place_kernels(d, w, cos, table, offset: int, length: int) -> np.ndarray:
    """One channel: impulse i adds w_i times the kernel at its angle and fractional delay,
    bilinear between the tabulated degrees and phases, from sample floor(d_i) + offset."""
    out = np.zeros(length)
    if not len(d):
        return out
    n_taps = table.shape[-1]
    theta = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    a0 = np.minimum(np.floor(theta).astype(np.int64), table.shape[0] - 2)
    fa = theta - a0
    n0, p0, fp = _split(d)
    taps = np.arange(n_taps)
    for s in range(0, len(d), _CHUNK):
        sl = slice(s, s + _CHUNK)
        a, p, wa, wp = a0[sl], p0[sl], fa[sl, None], fp[sl, None]
        k = ((1 - wa) * ((1 - wp) * table[a, p] + wp * table[a, p + 1])
             + wa * ((1 - wp) * table[a + 1, p] + wp * table[a + 1, p + 1]))
        at = n0[sl, None] + offset + taps
        inside = (at >= 0) & (at < length)
        out += np.bincount(at[inside], (k * w[sl, None])[inside], minlength=length)
    return out


class Binaural:
    """Two ears (left, right) through a SOFA HRTF: each image source is heard through the
    HRIR of its direction in the head frame (the array frame; the head's yaw is the
    array's), the nearest measurement or the measured triangle around it
    (``array.interpolation``). The HRIRs' common leading silence is removed
    (acoustics/hrtf.py), so the ears hear an image within a fraction of a millisecond of
    its arrival at the head's centre. The late tail has the HRTF's diffuse cross-spectra.

    ``interpolated`` blends time-aligned responses: each measured IR without its onset
    (acoustics/hrtf.py ``aligned_hrirs``: its delay behind its minimum-phase version)
    takes its barycentric weight, and the image is placed, ear by ear, at the blend of
    the three onsets, so the ITD is interpolated and the shapes add in phase. (Blending
    the IRs as measured adds copies a few samples apart: comb notches of -10 to -40 dB
    and ILD errors up to 1.7 dB between measurements 15° apart.)"""

    coincident = False
    n_channels = 2

    def __init__(self, array, fs: int):
        spec = array.spec
        self.fs = fs
        self.centre = np.asarray(array.centre, dtype=np.float64)
        self.yaw = array.yaw
        self.hrtf = _hrtf(str(array.hrtf), int(fs))
        self.mode = array.interpolation or "nearest"
        self.points = array_to_room(spec.positions(array), self.centre, array.yaw)  # the ears, for checks
        self.reference = self.centre

    def new_grid(self, n: int):
        return _IndexGrid(n)

    def add(self, grid, pos: np.ndarray, amp: np.ndarray, fade) -> None:
        v = pos - self.centre
        r = np.linalg.norm(v, axis=1)
        c, s = np.cos(np.radians(self.yaw)), np.sin(np.radians(self.yaw))
        u = np.stack([(c * v[:, 0] + s * v[:, 1]) / r, (-s * v[:, 0] + c * v[:, 1]) / r, v[:, 2] / r], axis=-1)
        from .hrtf import hrtf_weights  # loaded with the HRTF (_hrtf)

        idx, wk = hrtf_weights(self.hrtf, u, self.mode)
        t = r / SOUND_SPEED
        w = amp / (4 * np.pi * r) * fade_out(t, fade)
        if self.mode == "nearest":
            for k in range(idx.shape[1]):
                grid.add(idx[:, k], t * self.fs, w * wk[:, k])
            return
        from .hrtf import aligned_hrirs, hrir_onsets  # loaded with the HRTF (_hrtf)

        _, lead = aligned_hrirs(self.hrtf)
        onset = np.einsum("nk,nke->ne", wk, hrir_onsets(self.hrtf)[idx])  # [N, 2] samples, blended
        for e in range(2):  # rows 2m + e: measurement m's aligned IR at ear e
            for k in range(idx.shape[1]):
                grid.add(2 * idx[:, k] + e, t * self.fs + onset[:, e] - lead, w * wk[:, k])

    def render(self, grid) -> np.ndarray:
        """Impulses gathered per measurement (``interpolated``: per measurement and ear),
        rendered with the interpolator, then each measurement's signal through its HRIR
        pair (its aligned IR at that ear; one FFT product, summed)."""
        used, rows = grid.signals()
        n = grid.length
        if not len(used):
            return np.zeros((2, n))
        if self.mode == "nearest":
            irs = self.hrtf.irs[used].astype(np.float64)  # [U, 2, N]
            n_fft = sfft.next_fast_len(n + irs.shape[-1] - 1, real=True)
            spec = np.einsum("uf,uef->ef", sfft.rfft(rows, n_fft, workers=1), sfft.rfft(irs, n_fft, workers=1))
            return sfft.irfft(spec, n_fft, workers=1)[:, :n]
        from .hrtf import aligned_hrirs  # loaded with the HRTF (_hrtf)

        aligned, _ = aligned_hrirs(self.hrtf)
        irs = aligned[used // 2, used % 2].astype(np.float64)  # [U, N]
        n_fft = sfft.next_fast_len(n + irs.shape[-1] - 1, real=True)
        prod = sfft.rfft(rows, n_fft, workers=1) * sfft.rfft(irs, n_fft, workers=1)
        spec = np.stack([prod[used % 2 == e].sum(axis=0) for e in range(2)])
        return sfft.irfft(spec, n_fft, workers=1)[:, :n]

    def diffuse_noise(self, rng, n_sets: int, n: int) -> np.ndarray:
        return csd_noise(rng, n_sets, n, self.fs, self.diffuse_csd)

    def diffuse_csd(self, freqs) -> np.ndarray:
        from .hrtf import hrtf_diffuse_csd  # loaded with the HRTF (_hrtf)

        return hrtf_diffuse_csd(self.hrtf, np.atleast_1d(freqs))


class _IndexGrid:
    """Impulses per HRTF measurement index."""

    def __init__(self, length: int):
        self.length = int(length)
        self.idx, self.delays, self.weights = [], [], []

    def add(self, idx, delays, weights) -> None:
        keep = delays < self.length
        self.idx.append(idx[keep])
        self.delays.append(delays[keep])
        self.weights.append(weights[keep])

    def signals(self) -> tuple[np.ndarray, np.ndarray]:
        """(used measurement indices [U], their impulses rendered [U, length])."""
        if not self.idx:
            return np.zeros(0, dtype=np.int64), np.zeros((0, self.length))
        idx, d, w = np.concatenate(self.idx), np.concatenate(self.delays), np.concatenate(self.weights)
        used, row = np.unique(idx, return_inverse=True)
        grid = new_grid(len(used), self.length)
        order = np.argsort(row, kind="stable")
        bounds = np.searchsorted(row[order], np.arange(len(used) + 1))
        for u in range(len(used)):
            sel = order[bounds[u]:bounds[u + 1]]
            add_impulses(grid, u, d[sel], w[sel])
        return used, grid_to_signal(grid)


@lru_cache(maxsize=4)
def _hrtf(path: str, fs: int):
    """One HRTF per process, file and rate (reading and resampling a SOFA file is slow)."""
    from .hrtf import read_hrtf  # h5py: only binaural receivers need it at render time

    return read_hrtf(path, fs)


def spaced_csd(freqs, positions, alpha, axes, c: float = SOUND_SPEED) -> np.ndarray:
    """Diffuse-field cross-spectra [F, C, C] of first-order capsules (see :meth:`Spaced.diffuse_csd`)."""
    f = np.atleast_1d(np.asarray(freqs, dtype=np.float64))
    pos, al, o = (np.asarray(v, dtype=np.float64) for v in (positions, alpha, axes))
    if np.all(al == 1.0):
        return diffuse_coherence(pos, f, c).astype(np.complex128)
    delta = pos[:, None, :] - pos[None, :, :]
    d = np.linalg.norm(delta, axis=-1)
    e = np.divide(delta, d[..., None], out=np.zeros_like(delta), where=d[..., None] > 0)
    oe_i = np.einsum("ijk,ik->ij", e, o)  # o_i · e_ij
    oe_j = np.einsum("ijk,jk->ij", e, o)  # o_j · e_ij
    oo = o @ o.T
    x = 2 * np.pi * f[:, None, None] * d[None] / c
    from scipy.special import spherical_jn  # only directional capsules need it (slow to import)

    j0, j1, j2 = (spherical_jn(n, x) for n in (0, 1, 2))
    j1x = np.where(x > 1e-8, j1 / np.where(x > 1e-8, x, 1.0), 1.0 / 3.0)
    ai, aj = al[:, None], al[None, :]
    phi = (ai * aj * j0 + 1j * j1 * (ai * (1 - aj) * oe_j + aj * (1 - ai) * oe_i)
           + (1 - ai) * (1 - aj) * (oo * j1x - oe_i * oe_j * j2))
    return phi


MODELS = {
    ReceiverModel.SPACED: Spaced,
    ReceiverModel.AMBISONIC: Ambisonic,
    ReceiverModel.SPHERE: RigidSphere,
    ReceiverModel.HRTF: Binaural,
    ReceiverModel.MATRIX: Mixed,
}


def capsule_model(array, fs: int):
    """The capsule model of ``array`` (an ArrayPose) at ``fs`` Hz."""
    spec = array.spec
    model = spec.model
    if model == ReceiverModel.SPHERE:
        # an open sphere is free-field omnis at the capsule positions; recipes without a
        # baffle predate the rigid model
        if array.baffle in (None, Baffle.OPEN):
            return Spaced(array, fs)
    return MODELS[model](array, fs)
