"""The shoebox simulator's DC blocker without importing scipy.signal.

``scipy.signal`` loads most of scipy (about 1.4 s of CPU here), and every render process
paid for it to run one second-order high-pass. Here:

- :func:`butter2_highpass` designs the filter in closed form: the 2nd-order Butterworth
  prototype poles p = -exp(±jπ/4), the cut-off pre-warped to w = 4 tan(π f_c / fs) (the
  frequency axis normalised to fs = 2), the low-to-high-pass map p → w / p (two zeros at
  s = 0), and the bilinear transform z = (4 + s) / (4 - s), which puts both zeros at
  z = 1: H(z) = k (1 - z⁻¹)² / ((1 - q z⁻¹)(1 - q̄ z⁻¹)). Every step is the operation
  scipy's ``butter(2, f_c, "highpass", fs=fs, output="sos")`` performs, in its order, so
  the coefficients are the same float64 numbers (tests/acoustics/test_acoustics.py holds them to
  scipy's at many rates).
- :func:`sosfilt` runs the recursion in scipy's compiled second-order-section loop (the
  one ``scipy.signal.sosfilt`` calls), loaded from its own file: the loop is a few
  microseconds of import, where the package around it is seconds. If that file is not
  where scipy keeps it (another scipy layout), the filter goes through
  ``scipy.signal.sosfilt`` itself: the same numbers, only a slower start. A filter in
  numpy would need a Python loop over samples, and any other way to compute it (an FFT
  of its impulse response) changes the RIRs' last bits, and with them the datasets' bytes.
"""
from __future__ import annotations

import numpy as np

from ..core.compiled import scipy_extension


def butter2_highpass(cutoff: float, fs: float) -> np.ndarray:
    """Second-order Butterworth high-pass at ``cutoff`` Hz for ``fs`` Hz as one
    second-order section [[b0, b1, b2, 1, a1, a2]] (float64), bit for bit scipy's."""
    w = 4.0 * np.tan(np.pi * (cutoff / (fs / 2)) / 2.0)
    proto = -np.exp(1j * np.pi * np.array([-1.0, 1.0]) / 4)
    s_poles = w / proto
    k = np.real(1.0 / np.prod(-proto)) * np.real(16.0 / np.prod(4.0 - s_poles))
    z_poles = (4.0 + s_poles) / (4.0 - s_poles)
    # scipy pairs the poles by averaging each with its partner's conjugate
    q = (z_poles[z_poles.imag > 0] + z_poles[z_poles.imag < 0].conj())[0] / 2
    return np.array([[k, -2.0 * k, k, 1.0, -q.real - q.real, np.real(-q * -q.conj())]])


def sosfilt(sos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``scipy.signal.sosfilt(sos, x)`` along the last axis for real ``x``: float64, the
    same numbers (direct form II transposed, zero initial state)."""
    run = _compiled_loop()
    if run is None:
        from scipy.signal import sosfilt as scipy_sosfilt  # slow to import: only without the compiled loop's file

        return scipy_sosfilt(sos, x)
    x = np.asarray(x)
    y = np.array(x.reshape(-1, x.shape[-1]), dtype=np.float64, order="C")
    sos = np.ascontiguousarray(sos, dtype=np.float64)
    run(sos, y, np.zeros((len(y), len(sos), 2)))  # in place, on y and the state
    return y.reshape(x.shape)


def _compiled_loop():
    """scipy's ``_sosfilt(sos, x, zi)`` (filters the rows of x in place), or None."""
    module = scipy_extension("signal._sosfilt")
    return None if module is None else getattr(module, "_sosfilt", None)
