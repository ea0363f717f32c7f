"""Residual whiteness: the autocorrelation function with its ±1.96/√n bounds and the cumulated periodogram with
its Kolmogorov–Smirnov bounds (Box & Jenkins; the CTSM-R check of a grey-box model's one-step residuals).

Cumulated periodogram: C(f_k) = Σ_{j≤k} I(f_j) / Σ_j I(f_j) over the Fourier frequencies f_k = k/n, k = 1…q,
q = ⌊(n − 1)/2⌋; white noise keeps it within f/0.5 ± K_α/√(q − 1), K_0.05 = 1.358 (Kolmogorov's limit).
"""

from __future__ import annotations

import math

import numpy as np

KS_95 = 1.358


def acf(e: np.ndarray, lags: int = 48) -> np.ndarray:
    """Sample autocorrelation at lags 1…``lags``."""
    x = np.asarray(e, dtype=float) - np.mean(e)
    n = len(x)
    spec = np.fft.rfft(x, 2 * n)
    r = np.fft.irfft(spec * np.conj(spec))[:lags + 1]
    return r[1:] / r[0] if r[0] > 0 else np.zeros(lags)


def cumulated_periodogram(e: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(frequencies in cycles per sample, cumulated periodogram, the 95 % KS half-width)."""
    x = np.asarray(e, dtype=float) - np.mean(e)
    n = len(x)
    q = (n - 1) // 2
    I = np.abs(np.fft.rfft(x)[1:q + 1]) ** 2
    f = np.arange(1, q + 1) / n
    C = np.cumsum(I) / max(I.sum(), 1e-300)
    return f, C, KS_95 / math.sqrt(max(q - 1, 1))


def summary(e: np.ndarray, lags: int = 48) -> dict:
    """JSON-ready whiteness of one residual series: ``acf_outside`` (share of lags 1…``lags`` outside ±1.96/√n,
    about 5 % if white), ``acf_lag1``, ``cp_max_dev`` (largest distance of the cumulated periodogram from the white
    line), ``cp_bound`` and ``white`` (both within their 95 % bounds: the share outside at most 10 % and the
    periodogram inside its band)."""
    e = np.asarray(e, dtype=float)
    r = acf(e, lags)
    bound = 1.96 / math.sqrt(len(e))
    f, C, ks = cumulated_periodogram(e)
    dev = float(np.abs(C - f / 0.5).max()) if len(C) else 0.0
    outside = float(np.mean(np.abs(r) > bound)) if len(r) else 0.0
    return {"acf_lag1": float(r[0]) if len(r) else 0.0, "acf_bound": bound, "acf_outside": outside,
            "cp_max_dev": dev, "cp_bound": ks, "white": bool(dev <= ks and outside <= 0.10)}
