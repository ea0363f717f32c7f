"""The finder's noise model and multiple-testing control: tests that stay valid when the baseline is imperfect.

A calibrated baseline that cannot represent the machine leaves a residual well above sensor noise and strongly
autocorrelated; a likelihood ratio that assumes white noise then rejects for almost any candidate. As in
CTSM-R-style grey-box testing the noise model is taken from the baseline's own residual instead: per channel an
autoregressive model AR(p) (order by BIC, p ≤ :data:`MAX_ORDER`) fitted by least squares to the baseline's
residual on the screening rows. Residuals and candidate responses are passed through its inverse filter
(prewhitening) and divided by its innovation standard deviation, so that with nothing missing the whitened
residual is close to unit white noise and a drop of its sum of squares is a likelihood-ratio statistic,
χ²(free parameters). Structural misfit that the AR model describes counts as noise; a candidate must explain what
is left.

Multiple testing: within a round the candidates' p-values are judged by Benjamini–Hochberg at the round's level
(:func:`benjamini_hochberg`), the rounds of the forward search spend the false-discovery level α as α/2, α/4, …
(:func:`round_level`), so over all rounds the level stays below α.

numpy has no AR estimator and statsmodels is not a dependency: the least-squares fit below is a few lines.
"""

from __future__ import annotations

import numpy as np

MAX_ORDER = 4
MAX_PHI_SUM = 0.999  # an AR(1)-like root of the whitening filter kept inside the unit circle


def ar_fit(x: np.ndarray, max_order: int = MAX_ORDER) -> tuple[np.ndarray, float]:
    """AR coefficients a (x_t ≈ Σ a_k x_{t−k}) and innovation standard deviation of the series ``x``,
    order 0…``max_order`` by BIC (least squares on a common sample)."""
    x = np.asarray(x, dtype=float)
    x = x - x.mean() if len(x) else x
    n = len(x)
    if n < 4 * (max_order + 2):
        return np.zeros(0), float(np.std(x)) if n else 1.0
    target = x[max_order:]
    lags = np.column_stack([x[max_order - k:n - k] for k in range(1, max_order + 1)])
    best = (np.zeros(0), float(target @ target) / len(target))
    best_bic = len(target) * np.log(max(best[1], 1e-300))
    for p in range(1, max_order + 1):
        a = np.linalg.lstsq(lags[:, :p], target, rcond=None)[0]
        e = target - lags[:, :p] @ a
        var = float(e @ e) / len(target)
        bic = len(target) * np.log(max(var, 1e-300)) + p * np.log(len(target))
        if bic < best_bic:
            best, best_bic = (a, var), bic
    a, var = best
    if len(a) and a.sum() > MAX_PHI_SUM:  # a unit root would turn the filter into an integrator's inverse only
        a = a * (MAX_PHI_SUM / a.sum())
        e = whiten(x, a)[len(a):]
        var = float(e @ e) / max(len(e), 1)
    return a, float(np.sqrt(max(var, 1e-300)))


def whiten(x: np.ndarray, a: np.ndarray) -> np.ndarray:
    """e_t = x_t − Σ a_k x_{t−k}, and 0 for the first len(a) samples (they lack lags: left unwhitened, the first
    sample of a slow series carries its whole stationary variance and decides any regression on it); a 2-D
    ``x`` is filtered per column."""
    x = np.asarray(x, dtype=float)
    out = x.copy()
    for k, ak in enumerate(a, start=1):
        out[k:] -= ak * x[:-k]
    out[:len(a)] = 0.0
    return out


class NoiseModel:
    """Per-channel AR whitening filters fitted to a baseline's residual (one row per sample, one column per
    channel, in units of each channel's noise σ); :meth:`apply` whitens a series of one channel the same way."""

    def __init__(self, residual: np.ndarray, max_order: int = MAX_ORDER):
        fits = [ar_fit(residual[:, c], max_order) for c in range(residual.shape[1])]
        self.coefficients = [a for a, _ in fits]
        self.innovation = np.array([s for _, s in fits])

    @classmethod
    def white(cls, channels: int) -> NoiseModel:
        """White noise of unit spread in every channel (no whitening: the plain noise-weighted metric)."""
        model = cls(np.zeros((0, channels)))
        model.coefficients = [np.zeros(0)] * channels
        model.innovation = np.ones(channels)
        return model

    def apply(self, c: int, x: np.ndarray) -> np.ndarray:
        return whiten(x, self.coefficients[c]) / self.innovation[c]

    def describe(self, channels: list[str]) -> dict[str, dict[str, float]]:
        """Per channel: AR order, the sum of its coefficients (near 1: slow, strongly correlated misfit) and
        the innovation standard deviation in noise units."""
        return {ch: {"order": len(a), "phi_sum": round(float(a.sum()), 4), "innovation_sd": round(float(s), 4)}
                for ch, a, s in zip(channels, self.coefficients, self.innovation)}


def benjamini_hochberg(p_values: list[float], level: float) -> list[bool]:
    """Which hypotheses Benjamini–Hochberg rejects at false-discovery ``level`` (valid under positive
    dependence, the usual case of nested candidates fitted to one residual)."""
    p = np.asarray(p_values, dtype=float)
    m = len(p)
    if not m:
        return []
    order = np.argsort(p)
    passed = p[order] <= level * np.arange(1, m + 1) / m
    k = int(np.flatnonzero(passed).max()) + 1 if passed.any() else 0
    out = np.zeros(m, dtype=bool)
    out[order[:k]] = True
    return out.tolist()


def round_level(alpha: float, round_: int) -> float:
    """False-discovery level spent on forward-selection round ``round_`` (0-based): α/2^(round+1), summing to
    below α over any number of rounds."""
    return alpha / 2.0 ** (round_ + 1)
