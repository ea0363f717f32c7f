"""Uncertainty of a calibration: intervals from the Jacobian, unidentifiable parameters, near-null directions.

At the optimum the Jacobian J of the weighted, projected residual (central differences in the search
coordinates: log θ for log parameters) gives cov = s² (JᵀJ)⁻¹ with s² = RSS/(n − p); intervals are θ ± t·SE
mapped back (with exp for log parameters, so they are asymmetric and positive). The data cannot identify a
parameter when its interval spans more than a factor :data:`UNIDENTIFIABLE_RATIO` (log parameters), or when it
loads on a near-null singular direction of J (σ_j/σ_max < :data:`NULL_TOLERANCE`); the direction is reported as
the combination of search coordinates that the data leaves free. Sensitivities and offsets get the interval of
their (ridge) linear solve, conditional on θ. The intervals assume white residuals: on real recordings model
error is autocorrelated and they are optimistic (the mismatch map says where the model is wrong).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy import stats

from thermodrift.core.physics.calibration.objective import Problem, Sim, ridge_covariance

UNIDENTIFIABLE_RATIO = 10.0  # hi/lo of the interval beyond which a parameter counts as not identified
NULL_TOLERANCE = 1e-4        # σ_j/σ_max of J below which a singular direction counts as unidentifiable


@dataclass
class Estimate:
    """A calibrated parameter with its confidence interval (same unit); ``se`` in the search coordinate."""

    name: str
    paths: tuple[str, ...]
    value: float
    start: float
    low: float
    high: float
    se: float
    at_bound: bool
    unit: str
    log: bool = True

    @property
    def ratio(self) -> float:
        """hi/lo of the interval (1: exact; ≥ UNIDENTIFIABLE_RATIO: not identified; nan: not computed)."""
        if math.isnan(self.low):
            return math.nan
        return self.high / self.low if self.low > 0 else math.inf


def num(x: float) -> float | None:
    """JSON-safe number: None for an infinite or undefined value."""
    return float(x) if math.isfinite(x) else None


def jacobian(fun: Callable[[np.ndarray], np.ndarray], theta: np.ndarray, lo: np.ndarray, hi: np.ndarray,
             h: float = 1e-3) -> np.ndarray:
    """Central differences in the search coordinates (one-sided at a bound)."""
    cols = []
    for i in range(len(theta)):
        up, dn = theta.copy(), theta.copy()
        step = h * max(1.0, abs(theta[i])) if not np.isfinite(hi[i] - lo[i]) else h
        up[i] = min(theta[i] + step, hi[i])
        dn[i] = max(theta[i] - step, lo[i])
        cols.append((fun(up) - fun(dn)) / (up[i] - dn[i]))
    return np.column_stack(cols) if cols else np.empty((0, 0))


def uncertainty(problem: Problem, theta, J, s2, dof, level, lo, hi, sim: Sim, out: dict):
    """(estimates, unidentifiable, null directions, linear intervals) — see the module docstring."""
    free = problem.free
    q = float(stats.t.ppf(0.5 + level / 2, dof))
    estimates, nulls = [], []
    if free:
        _, sv, Vt = np.linalg.svd(J, full_matrices=False)
        smax = sv[0] if len(sv) and sv[0] > 0 else 1.0
        null = sv / smax < NULL_TOLERANCE
        for j in np.flatnonzero(null):
            v = Vt[j]
            combo = {free[i].name: round(float(v[i]), 3) for i in np.argsort(-np.abs(v)) if abs(v[i]) >= 0.2}
            nulls.append({"singular_ratio": float(sv[j] / smax), "log_combination": combo,
                          "meaning": "the data cannot tell apart changes along " + " ".join(
                              f"{c:+.2f}·{'log' if free[list(p.name for p in free).index(n)].log else ''}({n})"
                              for n, c in combo.items())})
        # Covariance on the identified subspace; a parameter that loads on a null direction has no finite
        # interval (a floored inverse would leak the null direction's huge variance into every parameter).
        keep = ~null
        cov = (Vt[keep].T / sv[keep] ** 2) @ Vt[keep] * s2
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        loads = np.abs(Vt[null]).max(axis=0) >= 0.2 if null.any() else np.zeros(len(free), bool)
        se[loads] = np.inf
        for i, p in enumerate(free):
            at_bound = bool(theta[i] <= lo[i] + 1e-9 or theta[i] >= hi[i] - 1e-9)
            half = q * se[i]
            if p.log:
                low, high = ((float(np.exp(theta[i] - half)), float(np.exp(theta[i] + half))) if half < 700
                             else (0.0, math.inf))
            else:
                low, high = float(theta[i] - half), float(theta[i] + half)
            estimates.append(Estimate(p.name, p.paths, p.from_search(theta[i]), p.value, low, high, float(se[i]),
                                      at_bound, p.unit, p.log))
    idx = {n: i for i, n in enumerate(sim.net.node_names)}
    sigma = {c.name: c.weight or c.sigma for c in problem.channels}
    for ch, p in problem.projected.items():
        node = idx[next(iter(next(s for s in problem.temp_sensors if s.name == ch).weights))]
        phi = sim.X[:, node] - sim.X_boundary[:, node]
        A = np.column_stack([phi, np.ones(len(phi))])
        var = np.linalg.pinv(A.T @ A)[0, 0] * s2 * sigma[ch] ** 2
        value = out["linear"][ch][p.name]
        half = q * math.sqrt(max(var, 0.0))
        low, high = max(value - half, 0.0), value + half
        estimates.append(Estimate(p.name, p.paths, value, p.value, low, high,
                                  half / q / value if value > 0 else math.inf, value <= 0.0, p.unit))
    linear_ci: dict[str, dict[str, list]] = {}
    for names, sensors in problem.groups.items():
        cov = ridge_covariance(out["designs"][names], problem.ridge[names])
        half = q * np.sqrt(np.maximum(np.diag(cov), 0.0) * s2)
        for s in sensors:
            values = out["linear"][s.name]
            linear_ci[s.name] = {n: [num(values[n] - h * sigma[s.name]), num(values[n] + h * sigma[s.name])]
                                 for n, h in zip([*names, "offset_um"], half)}
    in_null = {n for d in nulls for n in d["log_combination"]}
    unidentifiable = []
    for e in estimates:
        reasons = []
        if e.log and e.ratio > UNIDENTIFIABLE_RATIO:
            reasons.append(f"{level:.0%} interval spans a factor {e.ratio:.3g}" if math.isfinite(e.ratio)
                           else f"{level:.0%} interval reaches zero or infinity")
        if not e.log and not math.isfinite(e.se):
            reasons.append(f"{level:.0%} interval is unbounded")
        if e.name in in_null:
            reasons.append("loads on a near-null singular direction of the Jacobian")
        if reasons:
            if e.at_bound:
                reasons.append("estimate at its bound")
            unidentifiable.append({"parameter": e.name, "value": e.value, "ci": [num(e.low), num(e.high)],
                                   "reasons": reasons,
                                   "combinations": [d["log_combination"] for d in nulls
                                                    if e.name in d["log_combination"]]})
    return estimates, unidentifiable, nulls, linear_ci
