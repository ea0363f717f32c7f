"""Maximum-likelihood estimation of a stochastic grey-box model: bounded parameters, several deterministic starts,
intervals from the Hessian and the parameters the data cannot identify.

A *model* is anything with ``name``, ``parameters`` (a tuple of :class:`Param`) and ``system(values) -> System``
(values: a mapping of parameter name to value). Each parameter is searched on a scale η: the log of a parameter
that cannot be negative (its intervals stay positive and its relative precision is what the data set), the value
itself otherwise. Its bounds are kept by the optimiser itself (scipy's L-BFGS-B, a box on η), not by a squashing
transformation: a logit scale flattens the likelihood near a bound (its slope vanishes as e^−|η|), so a parameter
that strays there during the search never comes back, and a fit ends below the likelihood its own start had.

:func:`fit` maximises the Kalman filter's innovations log-likelihood (:func:`.kalman.run`) from the model's values
and ``starts − 1`` more points drawn around them from ``seed`` (η + N(0, 1), inside the box), keeping the best; the
best is then polished by a second L-BFGS-B run from where it stopped (a restart discards a curvature memory built
far from the optimum). The observed information is the Hessian of −log L by central differences on the η scale;
its inverse gives standard errors on η, mapped back to 95 % intervals. A parameter is *unidentifiable* when the
Hessian is near-singular along a direction it loads on (eigenvalue below 1e-8 of the largest), when its η standard
error exceeds 3 (an interval wider than a factor e^{±5.9}), or when it sits at a bound.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping, Protocol, Sequence

import numpy as np
from scipy.optimize import minimize
from scipy.stats import norm

from thermodrift.core.physics.stochastic import kalman
from thermodrift.core.physics.stochastic.sde import Series, System

Z95 = float(norm.ppf(0.975))
ETA_LIMIT = 25.0          # log scale: e^±25, the box where a positive parameter has no finite bound
SE_UNIDENTIFIABLE = 3.0   # η standard error above which a parameter is named unidentifiable
EIG_UNIDENTIFIABLE = 1e-8
HAC_SHARE = 10             # :func:`misfit_scale`'s Bartlett bandwidth: the rows over this (a fixed share, "fixed-b")


@dataclass(frozen=True)
class Param:
    """A model parameter: start value, bounds [low, high] (±inf allowed), unit and meaning."""

    name: str
    value: float
    low: float = 0.0
    high: float = math.inf
    unit: str = ""
    doc: str = ""

    @property
    def transform(self) -> str:
        """``log`` for a parameter that cannot be negative, ``identity`` otherwise."""
        return "log" if self.low >= 0 else "identity"

    @property
    def eta_bounds(self) -> tuple[float, float]:
        """The search box on the η scale (``±ETA_LIMIT`` where a log-scaled bound is 0 or infinite)."""
        if self.transform == "log":
            return (math.log(self.low) if self.low > 0 else -ETA_LIMIT,
                    math.log(self.high) if math.isfinite(self.high) else ETA_LIMIT)
        return (self.low, self.high)

    def to_eta(self, v: float) -> float:
        lo, hi = self.eta_bounds
        eta = math.log(max(v, 1e-300)) if self.transform == "log" else float(v)
        return min(max(eta, lo), hi)

    def from_eta(self, eta: float) -> float:
        lo, hi = self.eta_bounds
        eta = min(max(float(eta), lo), hi)
        v = math.exp(eta) if self.transform == "log" else eta
        return min(max(v, self.low), self.high)

    def at_bound(self, eta: float) -> bool:
        """Whether ``eta`` lies on the search box's edge (within 1e-6 of its width, or of 1)."""
        lo, hi = self.eta_bounds
        tol = 1e-6 * (hi - lo if math.isfinite(hi - lo) else 1.0)
        return eta <= lo + tol or eta >= hi - tol

    def with_value(self, v: float) -> "Param":
        return Param(self.name, float(min(max(v, self.low), self.high)), self.low, self.high, self.unit, self.doc)


class Model(Protocol):
    name: str
    parameters: tuple[Param, ...]

    def system(self, values: Mapping[str, float]) -> System: ...


@dataclass
class Estimate:
    """A fitted model: ``values`` (name → estimate), ``loglik``, ``n_params``, 95 % ``intervals`` (name → (lo,
    hi)), η standard errors ``se_eta``, ``unidentifiable`` (name → reason), the optimiser's work (``n_evals``,
    ``seconds``, ``starts``: the best log-likelihood of each start) and the data it was fitted on."""

    model: Model
    data: Series
    values: dict[str, float]
    loglik: float
    eta: np.ndarray
    n_evals: int
    seconds: float
    starts: list[float]
    cov_eta: np.ndarray | None = None
    se_eta: dict[str, float] = field(default_factory=dict)
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    unidentifiable: dict[str, str] = field(default_factory=dict)
    options: dict = field(default_factory=dict)

    @property
    def n_params(self) -> int:
        return len(self.model.parameters)

    @property
    def system(self) -> System:
        return self.model.system(self.values)

    def filtered(self, data: Series | None = None) -> kalman.Filtered:
        return kalman.run(self.system, self.data if data is None else data, **self.options)

    def derived(self, fn: Callable[[Mapping[str, float]], float], positive: bool = True
                ) -> tuple[float, tuple[float, float] | None]:
        """A function of the parameters with its 95 % interval by the delta method on the η scale (on the log
        of the value when ``positive``); the interval is None before :func:`information`."""
        params = self.model.parameters
        value = float(fn(self.values))
        if self.cov_eta is None:
            return value, None
        g = np.zeros(len(params))
        h = 1e-5
        f = (lambda v: math.log(max(v, 1e-300))) if positive else (lambda v: v)
        for i in range(len(params)):
            up, dn = self.eta.copy(), self.eta.copy()
            up[i] += h
            dn[i] -= h
            g[i] = (f(fn(_values(params, up))) - f(fn(_values(params, dn)))) / (2 * h)
        se = math.sqrt(max(float(g @ self.cov_eta @ g), 0.0))
        mid = f(value)
        lo, hi = mid - Z95 * se, mid + Z95 * se
        return value, ((math.exp(lo), math.exp(hi)) if positive else (lo, hi))

    def table(self) -> list[dict]:
        """One row per parameter: name, estimate, 95 % interval, unit, identifiable (JSON-ready)."""
        rows = []
        for p in self.model.parameters:
            lo, hi = self.intervals.get(p.name, (None, None))
            rows.append({"name": p.name, "estimate": self.values[p.name], "ci95": [lo, hi], "unit": p.unit,
                         "identifiable": p.name not in self.unidentifiable,
                         **({"why": self.unidentifiable[p.name]} if p.name in self.unidentifiable else {})})
        return rows


def _values(params: Sequence[Param], eta: np.ndarray) -> dict[str, float]:
    return {p.name: p.from_eta(e) for p, e in zip(params, eta)}


def loglik(model: Model, data: Series, values: Mapping[str, float], **options) -> float:
    """The innovations log-likelihood at ``values`` (−inf where the system is not usable). Callers that evaluate
    it many times hold BLAS to one thread (:func:`one_thread`): its matrices are a few states wide, and threaded
    BLAS on them costs ten times more than the arithmetic on a loaded machine."""
    try:
        return kalman.run(model.system(values), data, **options).loglik
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        return -math.inf


def loglik_gradient(model: Model, data: Series, eta: np.ndarray, lo: np.ndarray, hi: np.ndarray, **options
                    ) -> tuple[float, np.ndarray]:
    """The innovations log-likelihood at ``eta`` (the search scale) and its gradient along η (:mod:`.gradient`);
    (−inf, zeros) where the system is not usable."""
    from thermodrift.core.physics.stochastic import gradient

    params = model.parameters
    try:
        with np.errstate(all="ignore"):
            d = gradient.derivatives(lambda e: model.system(_values(params, e)), eta, lo, hi, data,
                                     options.get("init_rows", 96))
            ll, g = gradient.run(model.system(_values(params, eta)), d, data, **options)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        return -math.inf, np.zeros(len(eta))
    return (ll, g) if math.isfinite(ll) and np.isfinite(g).all() else (-math.inf, np.zeros(len(eta)))


def one_thread():
    """Context: BLAS on one thread (threadpoolctl ships with scikit-learn)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1)


def fit(model: Model, data: Series, *, seed: int = 0, starts: int = 3, maxiter: int = 300,
        information: bool = True, polish: bool = True, also: Sequence[Mapping[str, float]] = (),
        gradient: bool = True, **options) -> Estimate:
    """Maximum-likelihood estimate of ``model`` on ``data`` (see the module docstring); ``options`` go to the
    filter (``p0``, ``init_rows``, ``tol``, ``transient``). The search stops when an iteration gains less than
    1e-8 of the mean log-likelihood per sample (``ftol``) or after ``maxiter`` iterations per start;
    ``polish`` restarts from the best start's end with ``ftol`` 1e-10 (see the module docstring). ``also``:
    more start points (name → value; a missing name takes the model's value), searched before the random ones.
    ``gradient``: the log-likelihood's gradient by forward sensitivities (:mod:`.gradient`, one filter pass per
    gradient) rather than L-BFGS-B's finite differences (k + 1 passes per gradient, k parameters)."""
    params = model.parameters
    clock = time.perf_counter()
    n_evals = 0
    gradient = gradient and "x0" not in options
    scale = 1.0 / max(len(data), 1)

    bounds = [p.eta_bounds for p in params]
    lo, hi = np.array(bounds).T

    def objective(eta: np.ndarray) -> float:
        nonlocal n_evals
        n_evals += 1
        with np.errstate(all="ignore"):
            ll = loglik(model, data, _values(params, eta), **options)
        return -ll * scale if math.isfinite(ll) else 1e10

    def objective_grad(eta: np.ndarray) -> tuple[float, np.ndarray]:
        nonlocal n_evals
        n_evals += 1
        ll, g = loglik_gradient(model, data, eta, lo, hi, **options)
        return (-ll * scale, -g * scale) if math.isfinite(ll) else (1e10, np.zeros(len(eta)))

    eta0 = np.array([p.to_eta(p.value) for p in params])
    rng = np.random.default_rng(seed)
    given = [np.array([p.to_eta(v.get(p.name, p.value)) for p in params]) for v in also]
    drawn = [np.clip(eta0 + rng.standard_normal(len(eta0)), lo, hi) for _ in range(max(starts, 1) - 1)]
    points = [eta0, *given, *drawn]

    def search(x0: np.ndarray, ftol: float = 1e-8):
        if gradient:
            return minimize(objective_grad, x0, jac=True, method="L-BFGS-B", bounds=bounds,
                            options={"maxiter": maxiter, "ftol": ftol})
        return minimize(objective, x0, method="L-BFGS-B", bounds=bounds, options={"maxiter": maxiter, "ftol": ftol})

    best, start_ll = None, []
    with one_thread():
        for x0 in points:
            res = search(x0)
            start_ll.append(-float(res.fun) / scale)
            if best is None or res.fun < best.fun:
                best = res
        if polish:
            again = search(best.x, 1e-10)
            if again.fun < best.fun:
                best = again
        est = Estimate(model, data, _values(params, best.x), -float(best.fun) / scale, best.x.copy(), n_evals,
                       0.0, start_ll, options=dict(options))
        if information:
            add_information(est)
    est.seconds = time.perf_counter() - clock
    return est


def add_information(est: Estimate, h: float = 2e-3) -> None:
    """Observed information on the η scale (central differences), standard errors, 95 % intervals and the
    unidentifiable parameters, written into ``est``."""
    params, data, eta = est.model.parameters, est.data, est.eta
    k = len(params)

    def f(x: np.ndarray) -> float:
        with np.errstate(all="ignore"):
            return -loglik(est.model, data, _values(params, x), **est.options)

    with one_thread():
        H = _hessian(f, eta, h)
    est.n_evals += 1 + 2 * k + 2 * k * (k - 1)
    H = 0.5 * (H + H.T)
    why: dict[str, str] = {}
    for i, p in enumerate(params):
        if p.at_bound(eta[i]):
            why[p.name] = "at its bound"
    finite = np.isfinite(H).all()
    if finite:
        w, V = np.linalg.eigh(H)
        top = max(abs(w).max(), 1e-300)
        weak = w < EIG_UNIDENTIFIABLE * top
        for col in np.flatnonzero(weak):
            for i in np.flatnonzero(np.abs(V[:, col]) > 0.3):
                why.setdefault(params[i].name, "the likelihood is flat along a direction it loads on "
                                               "(near-singular Hessian)")
        w_inv = np.where(weak, 0.0, 1.0 / np.where(weak, 1.0, w))
        cov = (V * w_inv) @ V.T
        est.cov_eta = cov
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        for i, p in enumerate(params):
            if np.any(weak) and params[i].name in why:
                se[i] = math.inf
            est.se_eta[p.name] = float(se[i])
            if se[i] > SE_UNIDENTIFIABLE:
                why.setdefault(p.name, f"standard error {se[i]:.3g} on the {p.transform} scale")
            lo, hi = (p.from_eta(eta[i] - Z95 * se[i]), p.from_eta(eta[i] + Z95 * se[i])) if math.isfinite(
                se[i]) else (p.low, p.high)
            est.intervals[p.name] = (float(lo), float(hi))
    est.unidentifiable = why


def misfit_scale(est: Estimate) -> float:
    """How far the scores' long-run variance J exceeds the observed information H: tr(H⁻¹J)/k over the parameters
    not on a bound (H from :func:`add_information`, computed here when missing; J from the filter's scores,
    :func:`.gradient.scores`, with the Bartlett kernel over a tenth of the rows). About 1 where the model fits; a
    structurally wrong model leaves innovations correlated over hours, and J exceeds H. A likelihood-ratio
    statistic divided by it is the robust one (White's quasi-likelihood, in the mean scaling of Satorra and
    Bentler). Never below 1: a test it corrects only becomes more cautious. By hand: none of the project's
    libraries takes a long-run variance of given scores (statsmodels would, for this one sum)."""
    from thermodrift.core.physics.stochastic import gradient

    params, data = est.model.parameters, est.data
    if est.cov_eta is None:
        add_information(est)
    keep = [i for i, p in enumerate(params) if not p.at_bound(est.eta[i])]
    if not keep or est.cov_eta is None:
        return 1.0
    lo, hi = np.array([p.eta_bounds for p in params]).T
    with one_thread(), np.errstate(all="ignore"):
        d = gradient.derivatives(lambda e: est.model.system(_values(params, e)), est.eta, lo, hi, data,
                                 est.options.get("init_rows", 96))
        s = gradient.scores(est.system, d, data, **est.options)[:, keep]
    est.n_evals += 1 + 2 * len(params)
    s = s - s.mean(axis=0)
    J = s.T @ s
    lags = max(1, len(s) // HAC_SHARE)
    for lag in range(1, lags + 1):
        x = s[lag:].T @ s[:-lag]
        J += (1.0 - lag / (lags + 1)) * (x + x.T)
    c = float(np.trace(est.cov_eta[np.ix_(keep, keep)] @ J)) / len(keep)
    return max(c, 1.0) if math.isfinite(c) else math.inf


def _hessian(f: Callable[[np.ndarray], float], eta: np.ndarray, h: float) -> np.ndarray:
    """Central-difference Hessian of ``f`` at ``eta`` (step ``h``)."""
    k = len(eta)
    f0 = f(eta)
    H = np.zeros((k, k))
    for i in range(k):
        a = _unit(k, i, h)
        H[i, i] = (f(eta + a) - 2 * f0 + f(eta - a)) / h ** 2
    for i in range(k):
        for j in range(i + 1, k):
            a, b = _unit(k, i, h), _unit(k, j, h)
            H[i, j] = H[j, i] = (f(eta + a + b) - f(eta + a - b) - f(eta - a + b) + f(eta - a - b)) / (4 * h ** 2)
    return H


def _unit(k: int, i: int, h: float) -> np.ndarray:
    e = np.zeros(k)
    e[i] = h
    return e
