"""``scipy.fft``'s real transforms, bit for bit, without importing ``scipy.fft``.

The simulators, the late tail and the noise fields call ``rfft``, ``irfft``,
``next_fast_len`` and ``rfftfreq``. They run here through the compiled pocketfft module
that ``scipy.fft`` wraps (:func:`~tsel_data.core.compiled.scipy_extension`), with the argument
handling of ``scipy.fft._pocketfft.basic`` (dtype kept for float32/float64, zero-padding
or truncation to ``n``, "backward" normalisation), so every sample, and every dataset's
bytes, are what ``scipy.fft`` gives (tests/e2e/test_lean.py holds them equal). numpy's own FFT
differs from scipy's in float32's last bits, and ducc0's (tsel_data.dsp.fft, the convolution)
in all of them, so neither can stand in.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..core.compiled import scipy_extension


def _pocketfft():
    """scipy's compiled pocketfft, or None in another scipy layout (then each function
    calls scipy.fft's own: the same numbers, only a slower start)."""
    return scipy_extension("fft._pocketfft.pypocketfft")


def _real(x) -> np.ndarray:
    """``x`` as scipy's transforms take it: float32 and float64 kept (native byte order,
    aligned), other types as float64."""
    x = np.asarray(x)
    if x.dtype == np.float16:
        return x.astype(np.float32)
    if x.dtype.kind not in "fc":
        return x.astype(np.float64)
    return np.array(x, dtype=x.dtype.newbyteorder("="), copy=None if x.flags["ALIGNED"] else True)


def _fit(x: np.ndarray, n: int, axis: int) -> np.ndarray:
    """``x`` cut or zero-padded to ``n`` along ``axis``."""
    if n < 1:
        raise ValueError(f"invalid number of data points ({n}) specified")
    index = [slice(None)] * x.ndim
    index[axis] = slice(0, min(n, x.shape[axis]))
    if x.shape[axis] >= n:
        return x[tuple(index)]
    shape = list(x.shape)
    shape[axis] = n
    z = np.zeros(shape, x.dtype)
    z[tuple(index)] = x[tuple(index)]
    return z


def rfft(x, n: int | None = None, axis: int = -1, workers: int | None = None) -> np.ndarray:
    """``scipy.fft.rfft(x, n, axis, workers=workers)``."""
    pf = _pocketfft()
    if pf is None:
        import scipy.fft  # the fallback when pocketfft's own module is not there

        return scipy.fft.rfft(x, n, axis=axis, workers=workers)
    tmp = _real(x)
    if np.iscomplexobj(tmp):
        raise TypeError("x must be a real sequence")
    if n is not None:
        tmp = _fit(tmp, n, axis)
    elif tmp.shape[axis] < 1:
        raise ValueError(f"invalid number of data points ({tmp.shape[axis]}) specified")
    return pf.r2c(tmp, (axis,), True, 0, None, workers or 1)


def irfft(x, n: int | None = None, axis: int = -1, workers: int | None = None) -> np.ndarray:
    """``scipy.fft.irfft(x, n, axis, workers=workers)`` (scaled by 1/n)."""
    pf = _pocketfft()
    if pf is None:
        import scipy.fft  # the fallback when pocketfft's own module is not there

        return scipy.fft.irfft(x, n, axis=axis, workers=workers)
    tmp = _real(x)
    if not np.iscomplexobj(tmp):
        tmp = tmp + 0j
    if n is None:
        n = (tmp.shape[axis] - 1) * 2
        if n < 1:
            raise ValueError(f"Invalid number of data points ({n}) specified")
    else:
        tmp = _fit(tmp, n // 2 + 1, axis)
    return pf.c2r(tmp, (axis,), n, False, 2, None, workers or 1)


@lru_cache(maxsize=None)
def next_fast_len(target: int, real: bool = False) -> int:
    """``scipy.fft.next_fast_len(target, real)``."""
    pf = _pocketfft()
    if pf is None:
        import scipy.fft  # the fallback when pocketfft's own module is not there

        return scipy.fft.next_fast_len(target, real)
    return pf.good_size(target, real)


def rfftfreq(n: int, d: float = 1.0) -> np.ndarray:
    """``scipy.fft.rfftfreq(n, d)`` (numpy's, as scipy's is for numpy arrays)."""
    return np.fft.rfftfreq(n, d)
