"""Tiny SOFA ``SimpleFreeFieldHRIR`` files from an analytic spherical head, generated at test time.

- :func:`spherical_head_hrirs`: HRIRs [M, 2, N] of a rigid sphere of radius a with ears at
  ±y. Each ear hears a plane wave from u with Woodworth's delay (per ear, the incidence
  angle θ between u and the ear axis): τ = -(a/c) cos θ for θ < 90°, (a/c)(θ - π/2)
  behind it, so the ITD at ±90° is (a/c)(1 + π/2) ≈ 0.66 ms for a = 8.75 cm
  (R. S. Woodworth, Experimental Psychology, 1938). Fractional delays are Hann-windowed
  sincs (±32 taps). The head shadow is the magnitude of Brown & Duda's one-pole/one-zero
  filter (1 + j α ω / 2ω0) / (1 + j ω / 2ω0), ω0 = c/a, α(θ) = 1.05 + 0.95 cos(θ/150° · π):
  +6 dB at high frequencies at the near ear, -11 dB behind the head (C. P. Brown &
  R. O. Duda, "A structural model for binaural sound synthesis", IEEE Trans. Speech
  Audio Process. 6(5), 1998). Zero phase, so the ITD is Woodworth's alone; unit gain at
  DC, so the diffuse-field ear power is ~1 at low frequency. A raised-cosine low-pass
  from 0.7 to 0.9 x Nyquist stands for a measurement's anti-alias filter.
- :func:`make_hrtf_sofa`: a SimpleFreeFieldHRIR file of those HRIRs, written with netCDF4
  as SOFA tools write them, with options for the cases a reader must get right (right ear
  first, a turned listener, cartesian positions, Data.Delay, GeneralFIR, ...).
- :func:`make_broken_hrtf`: the malformed files the reader must refuse.
"""
from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from tsel_data.core.geometry import SOUND_SPEED, cart_to_sph, sph_to_cart

EARS = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])  # left, right (head frame)


def grid_directions(step_az: float = 15.0, elevations=(-30, 0, 30, 60, 90)) -> np.ndarray:
    """Head-frame unit vectors [M, 3]: rings of azimuth step ``step_az`` ° at each
    elevation (one direction at ±90°), azimuth from 0°."""
    out = []
    for el in elevations:
        az = [0.0] if abs(el) == 90 else np.arange(0.0, 360.0 - 1e-9, step_az)
        out.append(sph_to_cart(np.asarray(az), float(el), 1.0))
    return np.concatenate(out).reshape(-1, 3)


def woodworth_delays(directions, head_radius: float = 0.0875, c: float = SOUND_SPEED) -> np.ndarray:
    """Arrival times [M, 2] (s) at the left / right ear relative to the head centre."""
    cos = np.clip(np.asarray(directions, dtype=np.float64) @ EARS.T, -1.0, 1.0)
    theta = np.arccos(cos)
    return np.where(theta < np.pi / 2, -cos, theta - np.pi / 2) * head_radius / c


def spherical_head_hrirs(directions, fs: float = 48000, n_taps: int = 256, head_radius: float = 0.0875,
                         onset: float | np.ndarray = 0.002, c: float = SOUND_SPEED) -> np.ndarray:
    """HRIRs float64 [M, 2, n_taps]; the head centre hears the wave at ``onset`` s
    (a scalar or [M, 2] per ear)."""
    u = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    delay = (np.asarray(onset, dtype=np.float64) + woodworth_delays(u, head_radius, c)) * fs  # samples
    K = 32
    t = np.arange(n_taps) - delay[..., None]
    h = np.sinc(t) * np.where(np.abs(t) < K, 0.5 * (1.0 + np.cos(np.pi * t / K)), 0.0)
    nfft = 4 * n_taps
    x = 2.0 * np.pi * np.fft.rfftfreq(nfft, 1.0 / fs) / (2.0 * c / head_radius)  # ω / 2ω0
    theta = np.arccos(np.clip(u @ EARS.T, -1.0, 1.0))
    alpha = 1.05 + 0.95 * np.cos(theta / np.radians(150.0) * np.pi)
    shadow = np.abs((1.0 + 1j * alpha[..., None] * x) / (1.0 + 1j * x))
    # a measurement's anti-alias filter: without it fractional-delay sincs ring at Nyquist
    nu = np.fft.rfftfreq(nfft) * 2.0  # / Nyquist
    aa = np.where(nu < 0.7, 1.0, np.where(nu > 0.9, 0.0, 0.5 * (1.0 + np.cos(np.pi * (nu - 0.7) / 0.2))))
    return np.fft.irfft(np.fft.rfft(h, nfft) * shadow * aa, nfft)[..., :n_taps]


def make_hrtf_sofa(path, fs: float = 48000, step_az: float = 15.0, elevations=(-30, 0, 30, 60, 90),
                   head_radius: float = 0.0875, right_first: bool = False, view=None, up=(0.0, 0.0, 1.0),
                   listener=(0.0, 0.0, 0.0), cartesian: bool = False, n_taps: int = 256, distance: float = 1.2,
                   onset: float = 0.002, delay=None, conventions: str = "SimpleFreeFieldHRIR",
                   data_type: str = "FIR", receivers: int = 2, sampling_rate: bool = True,
                   source_position: bool = True, receiver_position: bool = True, nan_rows=(),
                   directions=None, name: str = "sphere") -> Path:
    """Write a SOFA HRIR file of :func:`spherical_head_hrirs`; returns its path.

    view / up: the listener's orientation in the file (its +x and +z axes); the head-frame
    directions stay those of the grid (or ``directions``), the file's SourcePosition being
    ``listener + R · distance · u`` (spherical about the origin unless ``cartesian``).
    right_first: the right ear is receiver 0 (ReceiverPosition says so). delay: samples
    (scalar, [2] per ear or [M, 2]) moved from the IRs into Data.Delay. receivers=3 adds
    a copy of the left ear. nan_rows: SourcePosition rows set to NaN.
    """
    from netCDF4 import Dataset

    u = grid_directions(step_az, elevations) if directions is None else np.asarray(directions, dtype=np.float64)
    M = len(u)
    d = None if delay is None else np.asarray(delay, dtype=np.float64)
    per_ear = 0.0 if d is None else np.broadcast_to(d, (M, 2))
    irs = spherical_head_hrirs(u, fs, n_taps, head_radius, onset - per_ear / fs)
    rec = np.array([[0.0, head_radius, 0.0], [0.0, -head_radius, 0.0]])
    if right_first:
        irs, rec = irs[:, ::-1], rec[::-1]
        d = None if d is None else (d[..., ::-1] if d.ndim and d.shape[-1] == 2 else d)
    if receivers == 3:
        irs = np.concatenate([irs, irs[:, :1]], axis=1)
        rec = np.concatenate([rec, np.zeros((1, 3))])

    x = np.asarray(view if view is not None else (1.0, 0.0, 0.0), dtype=np.float64)
    x = x / np.linalg.norm(x)
    z = np.asarray(up, dtype=np.float64) - np.dot(up, x) * x
    z /= np.linalg.norm(z)
    rot = np.stack([x, np.cross(z, x), z], axis=-1)  # columns: the head's axes
    pos = np.asarray(listener, dtype=np.float64) + distance * u @ rot.T

    root = Dataset(str(path), "w", format="NETCDF4")
    root.Conventions = "SOFA"
    root.Version = "2.1"
    root.SOFAConventions = conventions
    root.SOFAConventionsVersion = "1.0"
    root.DataType = data_type
    root.APIName = "tests/support/hrtf.py"
    root.RoomType = "free field"
    root.ListenerShortName = name
    root.DatabaseName = "tests"
    root.Title = "spherical head"
    R = irs.shape[1]
    for dim, n in (("M", M), ("N", n_taps), ("R", R), ("E", 1), ("I", 1), ("C", 3)):
        root.createDimension(dim, n)

    def var(name, dims, value, units=None, kind=None, dtype="f8"):
        v = root.createVariable(name, dtype, dims)
        if units:
            v.Units = units
        if kind:
            v.Type = kind
        v[:] = value
        return v

    var("ListenerPosition", ("I", "C"), np.asarray(listener, dtype=np.float64)[None], "metre", "cartesian")
    var("ListenerView", ("I", "C"), x[None], "metre", "cartesian")
    var("ListenerUp", ("I", "C"), z[None], "metre", "cartesian")
    if receiver_position:
        var("ReceiverPosition", ("R", "C", "I"), rec[:, :, None], "metre", "cartesian")
    var("EmitterPosition", ("E", "C", "I"), np.zeros((1, 3, 1)), "metre", "cartesian")
    if source_position:
        if cartesian:
            sp = pos.copy()
            units, kind = "metre", "cartesian"
        else:
            az, el, r = cart_to_sph(pos)
            sp = np.stack([az % 360.0, el, r], axis=-1)
            units, kind = "degree, degree, metre", "spherical"
        sp[list(nan_rows)] = np.nan
        var("SourcePosition", ("M", "C"), sp, units, kind)
    if sampling_rate:
        var("Data.SamplingRate", ("I",), [fs], "hertz")
    var("Data.IR", ("M", "R", "N"), irs)
    if d is not None:
        dd = np.broadcast_to(d, (M, 2)) if d.ndim == 2 else np.broadcast_to(d, (1, 2))
        if receivers == 3:
            dd = np.concatenate([dd, dd[:, :1]], axis=1)
        var("Data.Delay", ("M" if d.ndim == 2 else "I", "R"), dd)
    root.close()
    return Path(path)


BROKEN = ("text", "hdf5", "conventions", "tf", "receivers", "no_rate", "nan_positions", "no_positions",
          "few_directions", "negative_delay")


def make_broken_hrtf(path, kind: str) -> Path:
    """A file :func:`tsel_data.acoustics.hrtf.read_hrtf` must refuse; ``kind`` in :data:`BROKEN`."""
    path = Path(path)
    small = dict(step_az=60.0, elevations=(-30, 0, 30, 90), n_taps=64)
    if kind == "text":
        path.write_text("this is not a SOFA file\n")
    elif kind == "hdf5":
        with h5py.File(path, "w") as f:
            f.create_dataset("Data.IR", data=np.zeros((8, 2, 16)))
    elif kind == "conventions":
        make_hrtf_sofa(path, conventions="SingleRoomSRIR", **small)
    elif kind == "tf":
        make_hrtf_sofa(path, conventions="SimpleFreeFieldHRTF", data_type="TF", **small)
    elif kind == "receivers":
        make_hrtf_sofa(path, receivers=3, **small)
    elif kind == "no_rate":
        make_hrtf_sofa(path, sampling_rate=False, **small)
    elif kind == "nan_positions":
        make_hrtf_sofa(path, nan_rows=(3, 7), **small)
    elif kind == "no_positions":
        make_hrtf_sofa(path, source_position=False, **small)
    elif kind == "few_directions":
        make_hrtf_sofa(path, step_az=90.0, elevations=(0,), n_taps=64)
    elif kind == "negative_delay":
        make_hrtf_sofa(path, delay=-3.0, **small)
    else:
        raise ValueError(f"unknown broken HRTF kind {kind!r}; expected one of {BROKEN}")
    return path
