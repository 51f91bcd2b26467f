"""Scattering by a rigid sphere: the response of a capsule on a spherical baffle.

The capsules of spherical arrays (the DCASE "tetra" capsules on a 4.2 cm sphere, the
Eigenmike em32) sit on a rigid baffle, so what they hear depends on frequency and on the
angle θ between the capsule's outward normal and the direction towards the source:
about +6 dB on the side facing a high-frequency source (pressure doubling), a shadow
behind it, and the creeping waves that meet again in a bright spot at θ = 180°.

Time convention: the package's, a delay τ is exp(-j 2π f τ) (numpy rfft), i.e. fields
vary as exp(+jωt) and outgoing waves as exp(-jkr)/r. The spherical Hankel function of
outgoing waves is then h_n = h_n^(2) = j_n - i y_n. With k = 2π f / c, x = kR and
P_n the Legendre polynomials, the pressure on the surface divided by the free-field
pressure at the centre (no sphere) is (Rayleigh, "The Theory of Sound" §334; R. O. Duda
& W. L. Martens, "Range dependence of the response of a spherical head model",
J. Acoust. Soc. Am. 104(5), 1998, eqs. 1-2, written here in our sign convention):

    plane wave:               H(x, θ) = (1/x²) Σ_n i^(n-1) (2n+1) P_n(cos θ) / h_n'(x)
    point source at r = ρR:   H(x, ρ, θ) = -(ρ/x) e^{iρx} Σ_n (2n+1) P_n(cos θ) h_n(ρx) / h_n'(x)

(as ρ → ∞, h_n(ρx) → i^(n+1) e^{-iρx} / (ρx), which gives the plane wave). Both are
evaluated in one stable form, without Bessel functions that overflow at high order::

    H = Σ_n a_n P_n(cos θ),    a_n = -(e^{ix} / x) (2n+1) G_n / D_n(x)
    q_n(u) = h_n(u) / h_(n-1)(u):   q_0 = i,   q_n = (2n-1)/u - 1/q_(n-1)
    D_n(x) = h_n'(x) / h_n(x) = 1/q_n(x) - (n+1)/x
    G_n = Π_{k=1..n} q_k(ρx) / q_k(x)      (plane wave: q_k(∞) = i)

The recurrence is the upward three-term one of the h_n, h_(n+1) = (2n+1)/u h_n - h_(n-1),
which Duda & Martens use, divided through by h_n. Upwards it is stable because |h_n| is
dominated by y_n, the growing solution; carrying ratios instead of the h_n themselves
means nothing overflows (G_n simply underflows to 0 at high order).

At f = 0 the series has the potential-flow limit a_n = (2n+1)/(n+1) ρ^(-n): exactly 1
for a plane wave, but a point source at finite range gives the near side more and the
far side less: on axis Σ_n (2n+1)/(n+1) ρ^(-n) = 2ρ/(ρ-1) + ρ ln(1 - 1/ρ), so at
ρ = 2 the point facing the source is 8.3 dB above the centre (6.0 dB of it only
because it is nearer the source) -- the near-field range dependence of Duda & Martens.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..core.geometry import SOUND_SPEED
from ..dsp import realfft as sfft  # scipy.fft's numbers without its import

MAX_ORDER = 4000  # refuse point sources so close to the surface that the series needs more

# the point-source series ends in a geometric tail ~ 2 ρ^(-n) (see _order)
_TAIL_TOL = 1e-12


# --- modal series ------------------------------------------------------------------
def _order(x_max: float, rho: float) -> int:
    """Highest order n_max of the series for kR up to ``x_max`` and range ρ = r / R.

    Plane wave: n_max = ceil(x + 8 x^(1/3) + 4), Wiscombe's Mie criterion
    (x + 4 x^(1/3) + 2, Appl. Opt. 19, 1980) with both constants doubled: the truncation
    error, measured against scipy's spherical Bessel functions, is below 1e-10 relative
    for kR ≤ 120 (the classic constants leave ~1e-4). Beyond n ≈ x the terms of a plane
    wave fall faster than geometrically, but those of a point source only as
    (2n+1)/(n+1) ρ^(-n): it needs n_max ≥ log(2 ρ / ((ρ - 1) tol)) / log ρ as well
    (tol = 1e-12; ρ = 2: 42, ρ = 1.2: 166 orders).
    """
    n = math.ceil(x_max + 8.0 * x_max ** (1.0 / 3.0) + 4.0)
    if math.isfinite(rho):
        n = max(n, math.ceil(math.log(2.0 * rho / ((rho - 1.0) * _TAIL_TOL)) / math.log(rho)))
    return n


def _coefficients(x: np.ndarray, rho: float, n_max: int) -> np.ndarray:
    """Modal coefficients a_n [F, n_max + 1] (complex) of H = Σ a_n P_n(cos θ) at kR =
    ``x`` [F] (> 0) for a source at ρ = r / R (inf: a plane wave); see the module doc."""
    f = len(x)
    a = np.empty((f, n_max + 1), dtype=np.complex128)
    qx = np.full(f, 1j)
    qz = np.full(f, 1j)
    g = np.ones(f, dtype=np.complex128)
    z = rho * x
    pref = -np.exp(1j * x) / x
    for n in range(n_max + 1):  # a loop over orders, vectorised over frequencies
        if n:
            qx = (2 * n - 1) / x - 1.0 / qx
            if math.isfinite(rho):
                qz = (2 * n - 1) / z - 1.0 / qz
            g = g * (qz / qx)
        a[:, n] = pref * (2 * n + 1) * g / (1.0 / qx - (n + 1) / x)
    return a


def _static_coefficients(rho: float, n_max: int) -> np.ndarray:
    """a_n [n_max + 1] at f = 0: (2n+1)/(n+1) ρ^(-n), the rigid sphere in potential flow."""
    n = np.arange(n_max + 1)
    if not math.isfinite(rho):
        return (n == 0).astype(np.complex128)
    return ((2 * n + 1) / (n + 1) * rho ** (-n.astype(np.float64))).astype(np.complex128)


def _legendre(n_max: int, cos_theta: np.ndarray) -> np.ndarray:
    """P_n(cos θ) [n_max + 1, A] by Bonnet's recurrence (n+1) P_(n+1) = (2n+1) t P_n - n P_(n-1)."""
    t = np.asarray(cos_theta, dtype=np.float64)
    p = np.empty((n_max + 1, len(t)))
    p[0] = 1.0
    if n_max:
        p[1] = t
    for n in range(1, n_max):
        p[n + 1] = ((2 * n + 1) * t * p[n] - n * p[n - 1]) / (n + 1)
    return p


def _modal(freqs, radius: float, distance, c: float, order) -> np.ndarray:
    """a_n [F, N + 1] at ``freqs`` [F] (Hz, ≥ 0; 0 gets the static limit)."""
    f = np.atleast_1d(np.asarray(freqs, dtype=np.float64))
    if f.ndim != 1 or np.any(f < 0) or not np.all(np.isfinite(f)):
        raise ValueError("freqs must be a 1-D array of finite frequencies >= 0 Hz")
    if not radius > 0:
        raise ValueError(f"radius must be > 0 m, got {radius}")
    rho = math.inf if distance is None else float(distance) / float(radius)
    if not rho > 1.0:
        raise ValueError(f"the source must lie outside the sphere: distance {distance} m <= radius {radius} m")
    x = 2.0 * np.pi * f * float(radius) / float(c)
    x_max = float(x.max()) if len(x) else 0.0
    n_max = _order(x_max, rho) if order is None else int(order)
    if n_max < 0 or n_max > MAX_ORDER:
        raise ValueError(f"series order {n_max} outside [0, {MAX_ORDER}] (a source very close to the surface?)")
    a = np.empty((len(x), n_max + 1), dtype=np.complex128)
    zero = x == 0.0
    a[zero] = _static_coefficients(rho, n_max)
    if np.any(~zero):
        a[~zero] = _coefficients(x[~zero], rho, n_max)
    return a


def rigid_sphere_transfer(freqs, cos_theta, radius: float, distance: float | None = None,
                          c: float = SOUND_SPEED, order: int | None = None) -> np.ndarray:
    """Pressure on a rigid sphere over the free-field pressure at its centre, [F, A] complex.

    ``freqs`` [F] Hz (≥ 0; 0 allowed), ``cos_theta`` [A]: cosine of the angle between the
    surface point's outward normal and the direction towards the source; ``radius`` R
    (m). ``distance`` None: a plane wave; else a point source at that distance (m, >
    R) from the centre (Duda & Martens 1998). The reference is the pressure the same
    wave gives at the centre with no sphere, so the plane-wave response is 1 at f = 0
    and ~2 (+6 dB) at θ = 0 for kR ≫ 1; a near point source stays above 1 on the near
    side even at f = 0 (see the module doc). Phase: the package convention, so a plane
    wave's near side (θ = 0) leads by about R/c: H ≈ 2 exp(+j 2π f R / c) there at kR ≫ 1.

    ``order``: highest order n summed; None chooses it from the largest kR and ρ
    (:func:`_order`: error < 1e-10 relative).
    """
    ct = np.atleast_1d(np.asarray(cos_theta, dtype=np.float64))
    if ct.ndim != 1 or np.any(np.abs(ct) > 1.0 + 1e-12):
        raise ValueError("cos_theta must be a 1-D array of cosines in [-1, 1]")
    a = _modal(freqs, radius, distance, c, order)
    return a @ _legendre(a.shape[1] - 1, np.clip(ct, -1.0, 1.0))


def rigid_sphere_diffuse(freqs, radius: float, cos_gamma, c: float = SOUND_SPEED,
                         order: int | None = None) -> np.ndarray:
    """Cross-spectral density [F, G] (real) of two surface points γ apart in a diffuse field.

    The field: plane waves from all directions, uncorrelated, of equal power, such that
    the free-field pressure at the centre (no sphere) has PSD 1. Writing the plane-wave
    response as H(θ) = Σ_n (2n+1) b_n P_n(cos θ), b_n = i^(n-1) / (x² h_n'(x)), the mean
    over incidence directions u of H(u·p1) H*(u·p2) follows from the addition theorem
    (1/4π) ∫ P_n(u·p1) P_m(u·p2) dΩ = δ_nm P_n(p1·p2) / (2n+1):

        Φ(f, γ) = Σ_n (2n+1) |b_n(kR)|² P_n(cos γ)

    So Φ(f, 0) is the capsule's diffuse-field power response (the mean of |H|² over all
    directions; 1 at f = 0), and the coherence between the two capsules is
    Φ(f, γ) / Φ(f, 0), real because the field is symmetric. ``cos_gamma`` [G]: cosines
    of the angular separations. ``order`` as in :func:`rigid_sphere_transfer`.
    """
    cg = np.atleast_1d(np.asarray(cos_gamma, dtype=np.float64))
    if cg.ndim != 1 or np.any(np.abs(cg) > 1.0 + 1e-12):
        raise ValueError("cos_gamma must be a 1-D array of cosines in [-1, 1]")
    a = _modal(freqs, radius, None, c, order)
    n = np.arange(a.shape[1])
    # a_n = (2n+1) b_n, so (2n+1) |b_n|² = |a_n|² / (2n+1)
    return (np.abs(a) ** 2 / (2 * n + 1)) @ _legendre(a.shape[1] - 1, np.clip(cg, -1.0, 1.0))


# --- impulse responses -------------------------------------------------------------
# The response of the sphere to a plane-wave impulse lasts from the near side's arrival
# at -R/c to the creeping waves' first return to it, (3π/2) R/c after the centre's
# (measured at 48 kHz, R = 4.2 cm: beyond 8 R/c, |h| < 3e-4 of the peak).
_SUPPORT = 1.0 + 1.5 * math.pi  # in R/c
_TAPER = 16  # samples of raised-cosine fade at each end of the taps
_MARGIN = 4  # samples of flat window between the support and each fade
_DENSE = 8192  # frequency-sampling grid (bins of fs / _DENSE)


@dataclass(frozen=True, eq=False)  # eq=False: compared and hashed by identity, not by table
class SphereFilters:
    """Rigid-sphere impulse responses of a capsule, tabulated in angle (:func:`rigid_sphere_filters`).

    ``table`` [n_angles, n_taps] float64 (read-only): row a is the capsule's response to a
    plane-wave unit impulse (or one from a point source ``distance`` m from the centre)
    arriving from θ_a = a · 180° / (n_angles - 1) off its normal; tap n is the response at
    time (n - ``lead``) / fs relative to the wave passing the centre (as it would with no sphere). So an image source arriving at the centre at delay d samples (fractional) is
    placed by adding the row for its angle (:func:`interpolate_rows`) delayed by d - lead
    samples, e.g. through ism's fractional-delay interpolator.
    """

    fs: float
    radius: float
    c: float
    lead: int
    table: np.ndarray
    distance: float | None = None  # the point source's (m), None: a plane wave

    @property
    def thetas(self) -> np.ndarray:
        """Angles θ_a [n_angles] (radians) of the rows, uniform in [0, π]."""
        return np.linspace(0.0, np.pi, self.table.shape[0])


def rigid_sphere_filters(fs: float, radius: float, n_angles: int = 181, n_taps: int | None = None,
                         c: float = SOUND_SPEED, distance: float | None = None) -> SphereFilters:
    """Band-limited impulse responses of a point on a rigid sphere, [n_angles, n_taps] (see
    :class:`SphereFilters`), cached per (fs, radius, n_angles, n_taps, c, distance).

    ``distance`` None: a plane wave; else a point source that far (m) from the centre
    (Duda & Martens; the response is relative to the free-field pressure at the centre,
    as the plane wave's, so a near source's DC gain is the potential-flow limit of the
    module doc, not 1). Frequency sampling: H(f, θ) (:func:`rigid_sphere_transfer`) times the
    delay exp(-j 2π f lead / fs) on a grid of fs / 8192, inverse-transformed (the ideal
    response band-limited at fs/2), then cut to n_taps by a window that is flat over the
    response, [lead - R fs/c, lead + (3π/2) R fs/c] plus 4 samples each side, and fades
    over 16 samples beyond (raised cosine). The support is centred in the taps and the
    window is 1 all over it, so the window leaves the response alone and only fades the
    slow sinc tails of the band edge at fs/2. Rows are then scaled to their exact DC gain,
    H(0, θ) (1 for a plane wave; they were within 2e-3 of it).

    ``n_taps`` None: the smallest multiple of 16 that holds the support (1 + 3π/2) R/c
    plus both margins and fades: 64 at 24 kHz and 80 at 48 kHz for R = 4.2 cm, where the
    rows match H within 0.03 dB and 0.2° up to 0.8 · fs/2.
    """
    return _filters(float(fs), float(radius), int(n_angles), None if n_taps is None else int(n_taps), float(c),
                    None if distance is None else float(distance))


@lru_cache(maxsize=32)
def _filters(fs: float, radius: float, n_angles: int, n_taps: int | None, c: float,
             distance: float | None = None) -> SphereFilters:
    if n_angles < 2:
        raise ValueError(f"n_angles must be >= 2, got {n_angles}")
    span = _SUPPORT * radius * fs / c  # samples
    if n_taps is None:
        n_taps = 16 * math.ceil((span + 2 * (_TAPER + _MARGIN)) / 16)
    if n_taps < 4:
        raise ValueError(f"n_taps must be >= 4, got {n_taps}")
    taper = min(_TAPER, n_taps // 4)
    # the support [-R, (3π/2) R] · fs/c centred in the taps
    lead = int(round((n_taps - 1) / 2 - (_SUPPORT / 2 - 1.0) * radius * fs / c))
    n_fft = max(_DENSE, 8 * n_taps)
    f = sfft.rfftfreq(n_fft, 1.0 / fs)
    cos = np.cos(np.linspace(0.0, np.pi, n_angles))
    spec = rigid_sphere_transfer(f, cos, radius, distance, c=c).T
    spec *= np.exp(-2j * np.pi * f * (lead / fs))
    spec[:, -1] = spec[:, -1].real  # the Nyquist bin of a real response
    h = sfft.irfft(spec, n=n_fft, axis=-1, workers=1)[:, :n_taps]
    fade = 0.5 * (1.0 - np.cos(np.pi * (np.arange(taper) + 0.5) / taper))
    window = np.ones(n_taps)
    window[:taper], window[n_taps - taper:] = fade, fade[::-1]
    h *= window
    if distance is None:
        h /= h.sum(axis=1, keepdims=True)
    else:  # a near source's DC gain is not 1: the potential-flow limit
        h *= (rigid_sphere_transfer([0.0], cos, radius, distance, c=c)[0].real / h.sum(axis=1))[:, None]
    h.setflags(write=False)  # shared by every caller of the cache
    return SphereFilters(fs=fs, radius=radius, c=c, lead=lead, table=h, distance=distance)


def interpolate_rows(filters: SphereFilters, cos_theta) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation in θ between the table's rows: (idx0 [N] int64, w1 [N] float64).

    θ = arccos(cos_theta) sits between rows idx0 and idx0 + 1 (idx0 ≤ n_angles - 2), and
    the response there is ``(1 - w1) · table[idx0] + w1 · table[idx0 + 1]``, w1 ∈ [0, 1]
    (:func:`sphere_rows`). At 1° steps neighbouring rows differ in delay by at most
    0.1 sample (R = 4.2 cm, 48 kHz), so the interpolation error is ~0.1 dB at 0.8 · fs/2.
    """
    theta = np.arccos(np.clip(np.atleast_1d(np.asarray(cos_theta, dtype=np.float64)), -1.0, 1.0))
    pos = theta * ((filters.table.shape[0] - 1) / np.pi)
    idx0 = np.minimum(np.floor(pos).astype(np.int64), filters.table.shape[0] - 2)
    return idx0, pos - idx0


def sphere_rows(filters: SphereFilters, cos_theta) -> np.ndarray:
    """Impulse responses [N, n_taps] at angles of cosine ``cos_theta`` [N] (see :func:`interpolate_rows`)."""
    idx0, w1 = interpolate_rows(filters, cos_theta)
    t = filters.table
    return t[idx0] * (1.0 - w1)[:, None] + t[idx0 + 1] * w1[:, None]


def rigid_sphere_delay(cos_theta, radius: float, fmin: float = 200.0, fmax: float = 8000.0,
                       c: float = SOUND_SPEED) -> np.ndarray:
    """The delay (s) a capsule on a rigid sphere hears a plane wave with, relative to the
    wave passing the centre, as a localizer over [fmin, fmax] sees it: the least-squares
    slope of the unwrapped phase of H(f, θ) against 2πf (through the origin). The free
    field gives -R cos θ / c; the sphere lengthens it (towards 1.5 R/c at low
    frequencies on the near side, Kuhn's 3a/c ITD) and the far side hears the creeping
    waves. For SRP-PHAT steered at a rigid sphere (tsel verify)."""
    cos_theta = np.atleast_1d(np.asarray(cos_theta, dtype=np.float64))
    f = np.linspace(fmin, fmax, 256)
    phase = np.unwrap(np.angle(rigid_sphere_transfer(np.r_[0.0, f], cos_theta, radius, c=c)), axis=0)[1:]
    omega = 2 * np.pi * f[:, None]
    return -np.sum(omega * phase, axis=0) / np.sum(omega ** 2, axis=0)
