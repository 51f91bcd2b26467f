"""Binaural receivers: head-related impulse responses from a SOFA file (AES69).

A scene's image sources are heard through the HRIR of their direction in the head
frame, which is the array frame (x = front, y = left, z = up; the head's yaw is the
array yaw; see core/geometry.py).

Reading (:func:`read_hrtf`, through :mod:`tsel_data.acoustics.sofa`; SOFA files are netCDF-4, i.e. HDF5):

- Conventions: ``Conventions = "SOFA"`` and ``SOFAConventions = "SimpleFreeFieldHRIR"``.
  ``GeneralFIR`` is accepted too when it has R = 2 receivers, because several
  databases store HRIRs under it; it is read the same way. Transfer-function
  conventions (``SimpleFreeFieldHRTF``, ``GeneralTF``, DataType ``TF``), SOS and room
  conventions are refused: convert them to SimpleFreeFieldHRIR first.
- ``Data.IR`` [M, R = 2, N], ``Data.SamplingRate`` (one value, Hz).
- Directions: ``SourcePosition`` [M or 1, 3] with its ``Type`` (``spherical``: azimuth
  °, elevation °, radius m, or radians when ``Units`` says so; ``cartesian``: m) minus
  ``ListenerPosition`` (default the origin), rotated into the head frame by
  ``ListenerView`` / ``ListenerUp`` (the head's +x and +z axes; default +x, +z): a
  source at S is at R^T (S - L), R's columns being the head's axes.
- Ears: channel 0 = left, 1 = right. SOFA puts the left ear first; when
  ``ReceiverPosition`` (listener-local coordinates) has receiver 0 at smaller y than
  receiver 1 the file has the right ear first and the channels are swapped. Without a
  usable ReceiverPosition the file order is taken as left, right.
- ``Data.Delay`` ([1 or M, 1 or R], samples, "to be added to the IRs"): applied. Integer
  delays exactly (a shift); fractional ones with a Hann-windowed sinc of ±16 taps
  (errors ~1e-4 of the peak below 0.8 x Nyquist, content above it attenuated). Negative
  or non-finite delays are refused.
- ``fs``: if given and different from the file's rate, the IRs are resampled with
  ``scipy.signal.resample_poly`` (a ratio of integers up to 1000, e.g. 160/147).
- Onset: the leading silence common to all IRs is removed, minus a safety margin of
  :data:`ONSET_MARGIN_S`: a sample is silent while it is below
  :data:`ONSET_THRESHOLD_DB` re the peak of its own IR. The earliest ear of the
  earliest direction then starts ~0.1 ms after sample 0, so a direct path rendered at
  r / c arrives close to r / c (the ipsilateral ear of a lateral source leads the head
  centre by up to a / c ≈ 0.25 ms). ``Hrtf.lead`` is the number of samples removed, at
  ``Hrtf.fs``: ``irs[..., n]`` is sample ``n + lead`` of the file's IRs (delays applied,
  resampled).

Every malformed file raises one :class:`~tsel_data.errors.ConfigError` line naming the
file, what is wrong and how to fix it.

Directions to measurements (:func:`hrtf_weights`): ``nearest`` (the largest dot
product) or ``interpolated`` (blended time-aligned by the receiver: :func:`aligned_hrirs`,
:func:`hrir_onsets`): barycentric weights in the triangle of the convex hull of
the measured unit vectors (their spherical Delaunay triangulation) that the direction
passes through — the gains of vector-base amplitude panning normalised to sum 1
(V. Pulkki, "Virtual sound source positioning using vector base amplitude panning",
J. Audio Eng. Soc. 45(6), 1997). Hull facets that span an unmeasured region (a "hole":
a facet whose circumscribed cap — empty of measurements, by the Delaunay property —
has an angular radius of 90° or more, or over :data:`HOLE_FACTOR` (3) times the median
facet's; e.g. the flat bottom of a set without directions below -40°: 50° against ~5°)
are not interpolated across: directions through them (or through no facet at all, as
below a hemisphere) use the nearest measurement. Structured grids have no false holes;
random-like ones reach ~3x the median by chance and may lose a facet or two to the
nearest. A set in one plane (a horizontal ring) is interpolated linearly in angle
between neighbours around the ring, gaps over HOLE_FACTOR x the median gap again
falling back to the nearest. Cost: a k-d tree query and a few 3 x 3 products per
direction (tens of ms for 10^4 directions).

Diffuse field (:func:`hrtf_diffuse_csd`): quadrature over the measured directions with
weights = their spherical Voronoi cell areas (scipy.spatial.SphericalVoronoi), summing
to 1. For incomplete spheres the Voronoi cells bordering a hole are cut to the measured
region (their part outside every non-hole facet is counted on a Fibonacci grid of
>= 400 points per cell and removed; cells away from holes keep their exact area), so an
unmeasured cap contributes nothing: the field is isotropic over the measured directions
only, not extrapolated into the cap. A ring is weighted by arc length (isotropic in its
plane). Φ(f) = Σ_m w_m H_m(f) H_m(f)^H, so the mean ear power at low frequency is ~1
when the HRIRs have unit low-frequency gain (free-field normalised files); a measured
file carries its measurement gain. Binaural coherence: |Φ_LR| / sqrt(Φ_LL Φ_RR)
(:func:`binaural_coherence`; cf. I. Lindevald & A. Benade, "Two-ear correlation in the
statistical sound fields of rooms", J. Acoust. Soc. Am. 80(2), 1986).

Reference: AES69-2022, AES standard for file exchange — Spatial acoustic data file
format (SOFA); the SimpleFreeFieldHRIR convention.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

from ..core.files import check_input
from ..core.geometry import sph_to_cart
from ..core.h5str import as_str
from ..dsp import realfft as sfft  # scipy.fft's numbers without its import
from ..errors import ConfigError
from .sofa import in_listener_frame, open_sofa, position, rows_text

HRIR_CONVENTIONS = ("SimpleFreeFieldHRIR", "GeneralFIR")
MIN_DIRECTIONS = 6
ONSET_THRESHOLD_DB = -40.0  # re each IR's peak: below it a leading sample counts as silence
ONSET_MARGIN_S = 1e-4  # kept before the earliest onset: the rise and any pre-ringing
HOLE_FACTOR = 3.0  # a facet / ring gap this much larger than the median is unmeasured (random grids reach ~3x)
MODES = ("nearest", "interpolated")

_SINC_HALF = 16  # taps either side of a fractional Data.Delay kernel
_TOL = 1e-9  # barycentric coordinates down to -_TOL count as inside a triangle
_HOW = "give a SimpleFreeFieldHRIR SOFA file"


@dataclass(frozen=True, eq=False)
class Hrtf:
    """A set of head-related impulse responses.

    fs: Hz. directions: float64 [M, 3] unit vectors in the head frame (x front, y left,
    z up). irs: float32 [M, 2, N] (measurement, ear: 0 = left, 1 = right, sample).
    lead: samples (at ``fs``) removed from the start of the file's IRs, see the module
    docstring. source: the file. name: ListenerShortName, else the file name.

    Arrays are read-only; triangulation and quadrature weights are computed once per
    object and kept (not pickled).
    """

    fs: float
    directions: np.ndarray
    irs: np.ndarray
    lead: int
    source: str
    name: str
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        d = np.array(self.directions, dtype=np.float64).reshape(-1, 3)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        h = np.array(self.irs, dtype=np.float32)
        if h.ndim != 3 or h.shape[1] != 2 or h.shape[0] != len(d):
            raise ValueError(f"irs has shape {h.shape}; expected [M={len(d)}, 2, N]")
        d.setflags(write=False)
        h.setflags(write=False)
        object.__setattr__(self, "directions", d)
        object.__setattr__(self, "irs", h)

    @property
    def n_taps(self) -> int:
        return int(self.irs.shape[-1])

    def __repr__(self) -> str:
        M, _, N = self.irs.shape
        return f"Hrtf(name={self.name!r}, fs={self.fs:g}, M={M}, N={N}, lead={self.lead}, source={self.source!r})"

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k != "_cache"}

    def __setstate__(self, state):
        for k, v in state.items():
            if isinstance(v, np.ndarray):
                v.setflags(write=False)
            object.__setattr__(self, k, v)
        object.__setattr__(self, "_cache", {})


# --------------------------------------------------------------------------- reading


def read_hrtf(path, fs: float | None = None) -> Hrtf:
    """Read a SOFA SimpleFreeFieldHRIR file (see the module docstring for what is used
    and decided). ``fs`` (Hz): resample to it when it differs from the file's rate."""
    path = Path(path)
    if fs is not None and not (np.isfinite(fs) and fs > 0):
        raise ConfigError(f"{path}: HRTF sampling rate {fs!r} is not a positive number of Hz; give the scene's fs")
    check_input(path, ConfigError, "give the SOFA HRTF file itself")
    if not path.is_file():
        raise ConfigError(f"HRTF file {path} not found; check the path")
    with open_sofa(path, ConfigError, f"cannot be read as netCDF-4/HDF5); {_HOW}") as f:
        fs_file, irs, delays, directions, name = _read_file(f, path)
    if delays is not None:
        irs = _apply_delays(irs, delays)
    fs_out = fs_file if fs is None else float(fs)
    if abs(fs_out - fs_file) > 1e-6 * fs_file:
        irs = _resample(irs, fs_file, fs_out, path)
    irs, lead = _strip_onset(irs, fs_out, path)
    return Hrtf(fs=fs_out, directions=directions, irs=irs, lead=lead, source=str(path), name=name)


def _read_file(f, path: Path):
    """(fs, irs float64 [M, 2, N] left first, delays [M, 2] or None, directions [M, 3], name)."""
    if as_str(f.attrs.get("Conventions")) != "SOFA":
        raise ConfigError(f"{path}: not a SOFA file (no Conventions = \"SOFA\" attribute); {_HOW}")
    conv = as_str(f.attrs.get("SOFAConventions"))
    dtype = as_str(f.attrs.get("DataType")).upper()
    if conv.endswith("TF") or dtype.startswith("TF"):
        raise ConfigError(f"{path}: SOFAConventions {conv!r} (DataType {dtype or '?'}) holds transfer functions, "
                          f"not impulse responses; convert it to SimpleFreeFieldHRIR")
    if conv not in HRIR_CONVENTIONS:
        raise ConfigError(f"{path}: SOFAConventions {conv!r} is not an HRTF set; {_HOW} "
                          f"(or GeneralFIR with 2 receivers)")
    if dtype and dtype != "FIR":
        raise ConfigError(f"{path}: DataType {dtype!r}; an HRIR file has DataType FIR; {_HOW}")
    if "Data.IR" not in f:
        raise ConfigError(f"{path}: no Data.IR; {_HOW}")
    ds = f["Data.IR"]
    if ds.ndim != 3:
        raise ConfigError(f"{path}: Data.IR has shape {ds.shape}; expected [M, R = 2, N]")
    M, R, N = ds.shape
    if R != 2:
        raise ConfigError(f"{path}: Data.IR has {R} receivers; an HRTF has 2 (left and right ear); {_HOW}")
    if M < 1 or N < 1:
        raise ConfigError(f"{path}: Data.IR is empty (shape {ds.shape})")
    fs = _sampling_rate(f, path)
    irs = np.asarray(ds[()], dtype=np.float64)
    if not np.all(np.isfinite(irs)):
        raise ConfigError(f"{path}: Data.IR holds NaN or infinite samples; the file is damaged, export it again")
    delays = _delays(f, M, path)
    directions = _directions(f, M, path)
    if not _left_first(f, path):
        irs = irs[:, ::-1]
        delays = None if delays is None else delays[:, ::-1]
    name = as_str(f.attrs.get("ListenerShortName")).strip() or path.stem
    return fs, np.ascontiguousarray(irs), delays, directions, name


def _sampling_rate(f, path) -> float:
    if "Data.SamplingRate" not in f:
        raise ConfigError(f"{path}: no Data.SamplingRate; the file must give its sampling rate (Hz)")
    v = np.asarray(f["Data.SamplingRate"][()], dtype=np.float64).reshape(-1)
    if v.size == 0 or not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise ConfigError(f"{path}: Data.SamplingRate {v.tolist()} is not a positive number of Hz")
    if np.ptp(v) > 1e-6 * v[0]:
        raise ConfigError(f"{path}: Data.SamplingRate varies across measurements ({v.min():g}-{v.max():g} Hz); "
                          f"resample the IRs to one rate")
    return float(v[0])


def _delays(f, M: int, path) -> np.ndarray | None:
    """Data.Delay broadcast to [M, 2] samples, or None when absent or all zero."""
    if "Data.Delay" not in f:
        return None
    d = np.asarray(f["Data.Delay"][()], dtype=np.float64)
    if d.size == 1 or d.ndim == 1:
        d = d.reshape(1, -1)
    if d.ndim != 2 or d.shape[0] not in (1, M) or d.shape[1] not in (1, 2):
        raise ConfigError(f"{path}: Data.Delay has shape {d.shape}; expected [1 or M, 1 or 2] (samples)")
    if not np.all(np.isfinite(d)):
        raise ConfigError(f"{path}: Data.Delay holds NaN or infinite values; give delays in samples")
    if np.any(d < 0):
        raise ConfigError(f"{path}: negative Data.Delay ({d.min():g} samples); SOFA delays are added to the IRs "
                          f"and must be >= 0, shift the IRs instead")
    if not np.any(d):
        return None
    return np.broadcast_to(d, (M, 2)).copy()


def _directions(f, M: int, path) -> np.ndarray:
    lis = position(f, "ListenerPosition", M, path, ConfigError)
    at_origin = lis is None or not np.any(lis)
    # A spherical radius only matters when it is measured from somewhere else than the listener.
    src = position(f, "SourcePosition", M, path, ConfigError, direction=at_origin)
    if src is None:
        raise ConfigError(f"{path}: no SourcePosition; the HRTF directions are missing")
    rel = src if at_origin else src - lis
    rel = in_listener_frame(f, rel, M, path, ConfigError)
    norm = np.linalg.norm(rel, axis=1)
    bad = np.nonzero(norm < 1e-9)[0]
    if len(bad):
        raise ConfigError(f"{path}: SourcePosition coincides with ListenerPosition (rows {rows_text(bad)}); "
                          f"no direction to measure")
    u = rel / norm[:, None]
    n = len(np.unique(np.round(u, 6), axis=0))
    if n < MIN_DIRECTIONS:
        raise ConfigError(f"{path}: only {n} distinct source directions; an HRTF set needs at least "
                          f"{MIN_DIRECTIONS} (a sphere or a ring of measurements)")
    return u


def _left_first(f, path) -> bool:
    """False when ReceiverPosition puts receiver 0 to the right of receiver 1 (smaller y)."""
    if "ReceiverPosition" not in f:
        return True
    ds = f["ReceiverPosition"]
    v = np.asarray(ds[()], dtype=np.float64)
    if v.ndim == 3:  # [R, C, I or M] as SOFA defines it; [R, I or M, C] as some tools write it
        v = v[:, :, 0] if v.shape[1] == 3 else v[:, 0, :]
    if v.shape == (3, 2):
        v = v.T
    if v.shape != (2, 3) or not np.all(np.isfinite(v)):
        return True
    if as_str(ds.attrs.get("Type")).lower().startswith("spherical"):
        rad = "rad" in as_str(ds.attrs.get("Units")).lower().split(",")[0]
        ang = np.degrees(v[:, :2]) if rad else v[:, :2]
        v = sph_to_cart(ang[:, 0], ang[:, 1], v[:, 2])
    return not (v[0, 1] < v[1, 1] - 1e-9)


def _apply_delays(irs: np.ndarray, delays: np.ndarray) -> np.ndarray:
    """IRs [M, R, N] delayed by ``delays`` [M, R] samples (>= 0) -> [M, R, N + ceil(max
    delay)] (+16 samples of kernel tail for fractional delays).

    Sample 0 stays the file's time 0: the pre-ringing of a fractional kernel before it is
    dropped, as a measurement window starting there would."""
    M, R, N = irs.shape
    whole = np.round(delays)
    if np.allclose(delays, whole, atol=1e-6):
        k = whole.astype(np.int64)
        out = np.zeros((M, R, N + int(k.max())))
        np.put_along_axis(out, np.arange(N) + k[..., None], irs, axis=-1)
        return out
    K = _SINC_HALF
    top = int(np.ceil(delays.max()))
    t = np.arange(top + 2 * K + 1) - K - delays[..., None]  # kernel tap j delays by j - K
    kern = np.sinc(t) * np.where(np.abs(t) < K + 1, 0.5 * (1.0 + np.cos(np.pi * t / (K + 1))), 0.0)
    nfft = sfft.next_fast_len(N + kern.shape[-1] - 1, real=True)
    y = sfft.irfft(sfft.rfft(irs, nfft) * sfft.rfft(kern, nfft), nfft)
    return y[..., K:K + N + top + K]


def _resample(irs: np.ndarray, fs_in: float, fs_out: float, path) -> np.ndarray:
    import scipy.signal  # slow to import: only when a file needs resampling

    if float(fs_in).is_integer() and float(fs_out).is_integer():
        ratio = Fraction(int(fs_out), int(fs_in))
    else:
        ratio = Fraction(fs_out / fs_in).limit_denominator(1000)
    if ratio.numerator > 1000 or ratio.denominator > 1000 or abs(fs_in * ratio - fs_out) > 1e-6 * fs_out:
        raise ConfigError(f"{path}: cannot resample the HRIRs from {fs_in:g} Hz to {fs_out:g} Hz with a ratio of "
                          f"small integers; resample the file to {fs_out:g} Hz first")
    return scipy.signal.resample_poly(irs, ratio.numerator, ratio.denominator, axis=-1)


def _strip_onset(irs: np.ndarray, fs: float, path):
    """(float32 IRs without their common leading silence (minus the margin), samples removed)."""
    mag = np.abs(irs)
    peak = mag.max(axis=-1)
    if not np.any(peak > 0):
        raise ConfigError(f"{path}: every HRIR is silent (all zeros); the file is damaged, export it again")
    above = mag >= (peak * 10.0 ** (ONSET_THRESHOLD_DB / 20.0))[..., None]
    above &= (peak > 0)[..., None]
    first = np.where(above.any(axis=-1), above.argmax(axis=-1), irs.shape[-1])
    lead = max(0, int(first.min()) - int(np.ceil(ONSET_MARGIN_S * fs)))
    return irs[..., lead:].astype(np.float32), lead


# --------------------------------------------------------------------------- weights


def hrtf_weights(hrtf: Hrtf, u, mode: str = "nearest") -> tuple[np.ndarray, np.ndarray]:
    """Measurements to use for head-frame directions ``u`` [N, 3] (any length > 0).

    Returns (idx int [N, K], w float64 [N, K]), w >= 0 summing to 1 per row: the HRIR of
    direction n is Σ_k w[n, k] · hrtf.irs[idx[n, k]]. ``nearest``: K = 1, the
    measurement with the largest dot product. ``interpolated``: K = 3, barycentric
    weights in the enclosing triangle (unused slots: weight 0); directions through an
    unmeasured region get the nearest measurement (weights 1, 0, 0). See the module
    docstring.
    """
    u = np.asarray(u, dtype=np.float64)
    if u.shape[-1:] != (3,):
        raise ValueError(f"directions have shape {u.shape}; expected [N, 3]")
    shape = u.shape[:-1]
    u = u.reshape(-1, 3)
    norm = np.linalg.norm(u, axis=1)
    if not np.all(np.isfinite(norm)) or np.any(norm < 1e-12):
        raise ValueError("directions must be finite and non-zero")
    u = u / norm[:, None]
    if mode not in MODES:
        raise ValueError(f"unknown HRTF interpolation {mode!r}; expected one of {MODES}")
    mesh = _mesh(hrtf)
    near = mesh.rep[mesh.tree.query(u)[1]]
    if mode == "nearest":
        return near.reshape(shape + (1,)).astype(np.intp), np.ones(shape + (1,))
    idx = np.repeat(near[:, None], 3, axis=1).astype(np.intp)
    w = np.zeros((len(u), 3))
    w[:, 0] = 1.0
    if mesh.planar:
        _ring_weights(mesh, u, idx, w)
    else:
        _triangle_weights(mesh, u, idx, w)
    return idx.reshape(shape + (3,)), w.reshape(shape + (3,))


@dataclass(frozen=True)
class _Mesh:
    """Per-Hrtf geometry. rep: index (into hrtf.directions) of each distinct direction;
    inverse: distinct direction of each measurement; points, tree: the distinct ones
    and their cKDTree. Sphere: tri [F, 3] (indices into points) of the measured facets,
    inv [F, 3, 3] (barycentric coordinates = inv @ u), tri_tree over their centroids,
    hole_inv [H, 3, 3] the same for the hole facets, closed (the origin is strictly
    inside the hull, so each direction passes through exactly one facet), hole_vertex
    [D] bool (on a hole facet). Ring: basis [2, 3] of its plane, phi [D] angles sorted,
    order [D] (point of each phi), gap_ok [D] (the gap from phi[i] to the next is
    measured)."""

    rep: np.ndarray
    inverse: np.ndarray
    points: np.ndarray
    tree: object
    planar: bool
    tri: np.ndarray | None = None
    inv: np.ndarray | None = None
    tri_tree: object = None
    hole_inv: np.ndarray | None = None
    closed: bool = False
    hole_vertex: np.ndarray | None = None
    basis: np.ndarray | None = None
    phi: np.ndarray | None = None
    order: np.ndarray | None = None
    gap_ok: np.ndarray | None = None


def _mesh(hrtf: Hrtf) -> _Mesh:
    m = hrtf._cache.get("mesh")
    if m is None:
        m = hrtf._cache.setdefault("mesh", _build_mesh(hrtf.directions))
    return m


def _build_mesh(directions: np.ndarray) -> _Mesh:
    from scipy.spatial import ConvexHull, cKDTree  # scipy.spatial: only interpolated HRTFs need it

    # Repeated directions would be duplicate generators for the hull and the Voronoi diagram.
    _, rep, inverse = np.unique(np.round(directions, 6), axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    P = directions[rep]
    tree = cKDTree(P)
    centred = P - P.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    if s[-1] < 1e-6 * s[0]:
        n = np.linalg.svd(centred)[2][-1]
        e1 = np.cross(n, [0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.cross(n, [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        basis = np.stack([e1, np.cross(n, e1)])
        phi = np.arctan2(P @ basis[1], P @ basis[0])
        order = np.argsort(phi)
        phi = phi[order]
        gaps = np.diff(np.r_[phi, phi[0] + 2 * np.pi])
        gap_ok = gaps <= HOLE_FACTOR * np.median(gaps)
        return _Mesh(rep, inverse, P, tree, True, basis=basis, phi=phi, order=order, gap_ok=gap_ok)
    hull = ConvexHull(P)
    simp = hull.simplices
    A = P[simp].transpose(0, 2, 1)  # columns = the facet's vertices
    degenerate = np.abs(np.linalg.det(A)) < 1e-12
    offset = -hull.equations[:, 3]  # distance of the facet's plane from the origin
    # Angular radius of the facet's circumscribed cap: the cap beyond its plane, which
    # holds no measurement (the hull is the spherical Delaunay triangulation).
    rho = np.arccos(np.clip(offset, -1.0, 1.0))
    med = np.median(rho[~degenerate]) if np.any(~degenerate) else np.pi
    hole = degenerate | (rho >= np.pi / 2 - 1e-9) | (rho > HOLE_FACTOR * med)
    hole_vertex = np.zeros(len(P), dtype=bool)
    hole_vertex[simp[hole].reshape(-1)] = True
    tri = simp[~hole]
    inv = np.linalg.inv(A[~hole]) if len(tri) else np.zeros((0, 3, 3))
    hole_inv = np.linalg.inv(A[hole & ~degenerate]) if np.any(hole & ~degenerate) else np.zeros((0, 3, 3))
    cent = P[tri].sum(axis=1)
    cent /= np.maximum(np.linalg.norm(cent, axis=1, keepdims=True), 1e-300)
    tri_tree = cKDTree(cent) if len(tri) else None
    return _Mesh(rep, inverse, P, tree, False, tri=tri, inv=inv, tri_tree=tri_tree, hole_inv=hole_inv,
                 closed=bool(np.all(offset > 1e-9)), hole_vertex=hole_vertex)


def _in_cones(inv: np.ndarray, u: np.ndarray):
    """(facet [N], barycentric coordinates [N, 3], inside [N]): for each unit vector,
    the facet of ``inv`` [F, 3, 3] it is most inside (largest smallest coordinate)."""
    F = len(inv)
    fi = np.zeros(len(u), dtype=np.int64)
    lam = np.zeros((len(u), 3))
    if F == 0:
        return fi, lam, np.zeros(len(u), dtype=bool)
    flat = inv.reshape(3 * F, 3).T
    step = max(1, 1_000_000 // (3 * F))
    for s in range(0, len(u), step):
        la = (u[s:s + step] @ flat).reshape(-1, F, 3)  # one matrix product for every facet
        b = np.minimum(np.minimum(la[..., 0], la[..., 1]), la[..., 2]).argmax(axis=1)  # min(axis=-1) is slow
        fi[s:s + step], lam[s:s + step] = b, la[np.arange(len(b)), b]
    return fi, lam, lam.min(axis=1) >= -_TOL


def _locate(mesh: _Mesh, u: np.ndarray):
    """(facet index [N] into mesh.tri, barycentric coordinates [N, 3], found [N]) of unit
    vectors in the measured facets: among the facets of the 16 nearest centroids, then,
    for the rest, those in no hole (decided by the hole facets when the hull holds the
    origin) among all facets."""
    F = len(mesh.tri)
    found = np.zeros(len(u), dtype=bool)
    if F == 0 or len(u) == 0:
        return np.zeros(len(u), dtype=np.int64), np.zeros((len(u), 3)), found
    k = min(16, F)
    cand = mesh.tri_tree.query(u, k=k)[1].reshape(len(u), k)
    l = np.einsum("nkij,nj->nki", mesh.inv[cand], u)
    best = l.min(axis=-1).argmax(axis=1)
    rows = np.arange(len(u))
    fi, lam = cand[rows, best], l[rows, best]
    found = lam.min(axis=1) >= -_TOL
    rest = np.nonzero(~found)[0]
    if len(rest) and mesh.closed and len(mesh.hole_inv):
        rest = rest[~_in_cones(mesh.hole_inv, u[rest])[2]]
    if len(rest):
        f2, l2, ok = _in_cones(mesh.inv, u[rest])
        r = rest[ok]
        fi[r], lam[r], found[r] = f2[ok], l2[ok], True
    return fi, lam, found


def _triangle_weights(mesh: _Mesh, u, idx, w) -> None:
    fi, lam, found = _locate(mesh, u)
    if not np.any(found):
        return
    lam = np.clip(lam[found], 0.0, None)
    lam /= lam.sum(axis=1, keepdims=True)
    # a direction on an edge or at a vertex: no weight of 1e-17 on a far measurement
    lam[lam < 1e-12] = 0.0
    w[found] = lam / lam.sum(axis=1, keepdims=True)
    idx[found] = mesh.rep[mesh.tri[fi[found]]]


def _ring_weights(mesh: _Mesh, u, idx, w) -> None:
    x, y = u @ mesh.basis[0], u @ mesh.basis[1]
    ok = np.hypot(x, y) > 1e-9  # along the ring's axis every neighbour is as near: keep the nearest
    phi = np.arctan2(y, x)
    D = len(mesh.phi)
    i = (np.searchsorted(mesh.phi, phi, side="right") - 1) % D
    j = (i + 1) % D
    gap = (mesh.phi[j] - mesh.phi[i]) % (2 * np.pi)
    gap = np.where(gap == 0, 2 * np.pi, gap)
    t = np.clip(((phi - mesh.phi[i]) % (2 * np.pi)) / gap, 0.0, 1.0)
    ok &= mesh.gap_ok[i]
    idx[ok, 0] = mesh.rep[mesh.order[i[ok]]]
    idx[ok, 1] = mesh.rep[mesh.order[j[ok]]]
    idx[ok, 2] = idx[ok, 0]
    w[ok, 0], w[ok, 1], w[ok, 2] = 1.0 - t[ok], t[ok], 0.0


# --------------------------------------------------------------------------- time-aligned blending

# Samples kept before every aligned IR's onset: its rise and the fractional shift's ringing.
ALIGN_LEAD_S = 2.5e-4


def hrir_onsets(hrtf: Hrtf) -> np.ndarray:
    """Each IR's onset, float64 [M, 2] samples (at ``hrtf.fs``, into ``hrtf.irs``): its
    delay behind its own minimum-phase version (the lag of their cross-correlation peak,
    to 1/16 sample with a parabolic refinement). An HRIR is a minimum-phase response
    (what the pinna, head and torso do to the level) delayed by the excess-phase part
    (mostly the travel to the ear), so this is the travel time the ITD is made of: the
    difference of the two ears' onsets is the ITD. Computed once per object."""
    got = hrtf._cache.get("onsets")
    if got is None:
        got = hrtf._cache.setdefault("onsets", _onsets(hrtf.irs.astype(np.float64)))
    return got


def _onsets(h: np.ndarray) -> np.ndarray:
    N = h.shape[-1]
    n = sfft.next_fast_len(8 * N, real=True)
    H = sfft.rfft(h, n)
    mag = np.abs(H)
    floor = mag.max(axis=-1, keepdims=True) * 1e-6  # -120 dB: no log of zero
    cep = sfft.irfft(np.log(np.maximum(mag, floor)), n)
    fold = np.zeros_like(cep)  # the cepstrum folded onto its causal half: the minimum-phase version
    fold[..., 0] = cep[..., 0]
    fold[..., 1:n // 2] = 2.0 * cep[..., 1:n // 2]
    if n % 2 == 0:
        fold[..., n // 2] = cep[..., n // 2]
    h_min = np.exp(sfft.rfft(fold, n))
    up = 16
    xc = sfft.irfft(H * np.conj(h_min), n * up)  # cross-correlation at 1/up sample; lag k at k mod n·up
    span = N * up  # onsets lie within the IR (and a little before its start, pre-ringing)
    lags = np.concatenate([np.arange(-span // 4, 0), np.arange(span)])
    vals = xc[..., lags % (n * up)]
    k = np.argmax(vals, axis=-1)
    y1 = np.take_along_axis(vals, k[..., None], -1)[..., 0]
    y0 = np.take_along_axis(vals, np.clip(k - 1, 0, len(lags) - 1)[..., None], -1)[..., 0]
    y2 = np.take_along_axis(vals, np.clip(k + 1, 0, len(lags) - 1)[..., None], -1)[..., 0]
    den = y0 - 2.0 * y1 + y2
    frac = np.where(np.abs(den) > 1e-300, 0.5 * (y0 - y2) / np.where(np.abs(den) > 1e-300, den, 1.0), 0.0)
    return (lags[k] + np.clip(frac, -0.5, 0.5)) / up


def aligned_hrirs(hrtf: Hrtf) -> tuple[np.ndarray, int]:
    """The IRs with their onsets removed: (float32 [M, 2, N] each shifted so that its onset
    (:func:`hrir_onsets`) falls on sample ``lead``, ``lead``): the responses that
    ``interpolated`` blends, which then differ only in shape, not in delay. A fractional
    shift by a phase ramp (the IRs are band-limited); computed once per object."""
    got = hrtf._cache.get("aligned")
    if got is None:
        onsets = hrir_onsets(hrtf)
        lead = int(np.ceil(ALIGN_LEAD_S * hrtf.fs))
        h = hrtf.irs.astype(np.float64)
        N = h.shape[-1]
        n = sfft.next_fast_len(2 * N + lead, real=True)
        f = np.arange(n // 2 + 1) / n
        shift = onsets - lead  # samples earlier
        spec = sfft.rfft(h, n) * np.exp(2j * np.pi * f * shift[..., None])
        out = sfft.irfft(spec, n)[..., :N].astype(np.float32)
        out.setflags(write=False)
        got = hrtf._cache.setdefault("aligned", (out, lead))
    return got


# --------------------------------------------------------------------------- diffuse field


def hrtf_diffuse_weights(hrtf: Hrtf) -> np.ndarray:
    """Quadrature weights [M] (sum 1) of the measured directions for an isotropic field:
    spherical Voronoi cell areas cut to the measured region (a ring: arc lengths).
    Repeated directions share their cell equally. See the module docstring."""
    w = hrtf._cache.get("quadrature")
    if w is None:
        w = hrtf._cache.setdefault("quadrature", _quadrature(_mesh(hrtf)))
    return w


def _quadrature(mesh: _Mesh) -> np.ndarray:
    if mesh.planar:
        gaps = np.diff(np.r_[mesh.phi, mesh.phi[0] + 2 * np.pi]) * mesh.gap_ok
        a = np.empty(len(mesh.phi))
        a[mesh.order] = 0.5 * (gaps + np.roll(gaps, 1))  # half of the gap on either side
    else:
        from scipy.spatial import SphericalVoronoi  # only irregular HRTF grids need it

        a = SphericalVoronoi(mesh.points, radius=1.0, center=np.zeros(3)).calculate_areas()
        if np.any(mesh.hole_vertex):
            a = a * _measured_fraction(mesh)
    counts = np.bincount(mesh.inverse, minlength=len(a))
    w = a[mesh.inverse] / counts[mesh.inverse]
    return w / w.sum()


def _measured_fraction(mesh: _Mesh) -> np.ndarray:
    """Fraction [D] of each Voronoi cell inside the measured facets: 1 for cells of
    vertices away from holes; for those on a hole, counted on a Fibonacci grid of the
    sphere (≥ ~400 points per cell)."""
    D = len(mesh.points)
    n = int(np.clip(400 * D, 50_000, 1_000_000))
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    az = np.pi * (1.0 + 5.0**0.5) * k
    r = np.sqrt(1.0 - z * z)
    grid = np.stack([r * np.cos(az), r * np.sin(az), z], axis=-1)
    owner = mesh.tree.query(grid)[1]
    edge = mesh.hole_vertex[owner]
    if mesh.closed:  # each point is in exactly one facet: measured unless in a hole
        inside = ~_in_cones(mesh.hole_inv, grid[edge])[2]
    else:
        inside = _locate(mesh, grid[edge])[2]
    total = np.bincount(owner[edge], minlength=D)
    kept = np.bincount(owner[edge][inside], minlength=D)
    frac = np.ones(D)
    has = total > 0
    frac[has] = kept[has] / total[has]
    return frac


def hrtf_diffuse_csd(hrtf: Hrtf, freqs) -> np.ndarray:
    """Interaural cross-spectral matrix [F, 2, 2] (complex128) in an isotropic diffuse
    field at ``freqs`` [F] (Hz): Φ_ab(f) = Σ_m w_m H_a,m(f) conj(H_b,m(f)), w from
    :func:`hrtf_diffuse_weights`, H the DTFT of ``hrtf.irs`` (a = 0 left, 1 right).

    Computed through the weighted interaural correlations r_ab[l] (FFT), whose DTFT is
    Φ_ab, so any frequencies cost F x (2N - 1) operations."""
    f = np.asarray(freqs, dtype=np.float64).reshape(-1)
    w = hrtf_diffuse_weights(hrtf)
    h = hrtf.irs.astype(np.float64)
    N = h.shape[-1]
    nfft = sfft.next_fast_len(2 * N - 1, real=True)
    X = sfft.rfft(h, nfft)
    S = np.einsum("m,mak,mbk->abk", w, X, np.conj(X))
    r = sfft.irfft(S, nfft)
    lags = np.r_[np.arange(N), np.arange(-(N - 1), 0)]
    rr = np.concatenate([r[..., :N], r[..., nfft - (N - 1):]], axis=-1) if N > 1 else r[..., :1]
    out = np.empty((len(f), 2, 2), dtype=np.complex128)
    step = max(1, 4_000_000 // len(lags))
    for s in range(0, len(f), step):
        E = np.exp(-2j * np.pi * np.outer(f[s:s + step], lags) / hrtf.fs)
        out[s:s + step] = np.einsum("fl,abl->fab", E, rr)
    return out


def binaural_coherence(csd) -> np.ndarray:
    """Binaural coherence |Φ_LR| / sqrt(Φ_LL Φ_RR) [F] (in [0, 1]) of cross-spectral matrices [F, 2, 2]."""
    csd = np.asarray(csd)
    den = np.sqrt(np.abs(csd[:, 0, 0].real * csd[:, 1, 1].real))
    return np.abs(csd[:, 0, 1]) / np.maximum(den, 1e-300)
