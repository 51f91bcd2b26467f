"""Measurements on signals the physics tests share."""
import numpy as np


def lag(a, b, max_lag):
    """Lag (samples, to 0.1) of b relative to a, from the cross-correlation peak (upsampled 10x)."""
    n = len(a) + len(b)
    spec = np.fft.rfft(b, n) * np.conj(np.fft.rfft(a, n))
    cc = np.fft.irfft(spec / (np.abs(spec) + 1e-12), n * 10)  # PHAT + interpolation
    lags = np.concatenate([np.arange(0, max_lag * 10 + 1), np.arange(-max_lag * 10, 0)])
    vals = np.concatenate([cc[: max_lag * 10 + 1], cc[-max_lag * 10:]])
    return lags[np.argmax(vals)] / 10
