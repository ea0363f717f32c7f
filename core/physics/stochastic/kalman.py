"""The continuous–discrete Kalman filter over an exactly discretised linear SDE: innovations, their covariance
and the log-likelihood, and k-step predictions.

Per sample: innovation e_k = y_k − C x_k|k−1 − D u_k with covariance S_k = C P_k|k−1 Cᵀ + R, log-likelihood Σ_k −½
(p log 2π + log det S_k + e_kᵀ S_k⁻¹ e_k). The steps are the compensator's (one home:
:mod:`thermodrift.compensator.physics`): within a run of samples that share a step (level, Δt) the filter runs
time-varying (:func:`kalman_update`) until the predicted covariance reaches the stationary one of the discrete
Riccati equation (relative difference below ``tol``) or over the first ``transient`` samples at most, then as the
stationary filter (:func:`steady_filter`, the filtered state x_k = F x_{k−1} + G u_{k−1} + K (y_k − D u_k)), a
linear recursion that the project's propagator runs in C (:func:`~thermodrift.core.physics.integrate.propagate`). A
regularly sampled building is one such run: the likelihood is exact but for slow modes whose covariance has not
settled after ``transient`` samples (200 by default, 50 h at 15 min), and costs a few milliseconds for 7,000
samples.

Initial state: the equilibrium at the mean inputs of the first ``init_rows`` samples, shifted so that the measured
states read the first measurement, with covariance ``p0²·I`` (state units²).

Why not statsmodels' state-space MLE or filterpy: both work in discrete time on given matrices; the continuous-time
parameterisation with exact, Van-Loan discretisation per parameter vector, the per-level steps of the machine
networks and the shared compensator step are what this module is, and neither library would remove them (statsmodels
would add a dependency to run the loop that the compensator's step already runs)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thermodrift.compensator.physics import kalman_update, steady_filter
from thermodrift.core.physics.integrate import propagate
from thermodrift.core.physics.stochastic.sde import Series, System

LOG_2PI = float(np.log(2.0 * np.pi))


@dataclass(frozen=True)
class Filtered:
    """The filter's pass over a series: innovations ``e`` (rows × p), their variances ``S`` (rows × p × p),
    predicted states ``x_pred`` and filtered states ``x_filt`` (rows × n) and the log-likelihood ``loglik``."""

    e: np.ndarray
    S: np.ndarray
    x_pred: np.ndarray
    x_filt: np.ndarray
    loglik: float

    @property
    def standardized(self) -> np.ndarray:
        """Innovations scaled by their standard deviation (rows × p): white N(0, 1) if the model is right."""
        return self.e / np.sqrt(np.einsum("kii->ki", self.S))


def initial_state(system: System, data: Series, init_rows: int = 96) -> np.ndarray:
    """Equilibrium at the first ``init_rows`` samples' mean inputs, measured states set to the first reading."""
    u0 = data.u[:init_rows].mean(axis=0)
    x = system.steady_state(int(data.level[0]), u0)
    C = system.C
    if len(C):
        x = x + np.linalg.pinv(C) @ (data.y[0] - system.D @ data.u[0] - C @ x)
    return x


def run(system: System, data: Series, *, p0: float = 1.0, init_rows: int = 96, tol: float = 1e-9,
        transient: int = 200, x0: np.ndarray | None = None) -> Filtered:
    """The filter over ``data`` (see the module docstring)."""
    C, D, R = system.C, system.D, system.R
    N, n, p = len(data), system.n_states, len(C)
    y = data.y - data.u @ D.T
    e = np.empty((N, p))
    S = np.empty((N, p, p))
    xp = np.empty((N, n))
    xf = np.empty((N, n))
    x = initial_state(system, data, init_rows) if x0 is None else np.asarray(x0, dtype=float)
    P = np.eye(n) * p0 ** 2
    xp[0] = x
    e[0] = y[0] - C @ x
    x, P, S[0] = kalman_update(x, P, e[0], C, R)
    xf[0] = x
    if N > 1:
        levels, dts = data.steps()
        change = np.flatnonzero((levels[1:] != levels[:-1]) | (dts[1:] != dts[:-1])) + 1
        cache: dict[tuple, tuple] = {}
        for a, b in zip(np.r_[0, change], np.r_[change, N - 1]):  # steps a..b−1 reach rows a+1..b
            key = (int(levels[a]), float(dts[a]))
            if key not in cache:
                Phi, Gam, Q = system.discrete(*key)
                cache[key] = (Phi, Gam, Q, *steady_filter(Phi, Gam, C, Q, R))
            Phi, Gam, Q, F, G, K, Pss = cache[key]
            j = a + 1
            while j <= b and j <= transient:  # time-varying until the predicted covariance is stationary
                x = Phi @ x + Gam @ data.u[j - 1]
                P = Phi @ P @ Phi.T + Q
                xp[j] = x
                e[j] = y[j] - C @ x
                x, Pf, S[j] = kalman_update(x, P, e[j], C, R)
                xf[j] = x
                j += 1
                done = np.abs(P - Pss).max() <= tol * np.abs(Pss).max()
                P = Pf
                if done:
                    break
            if j <= b:  # the stationary filter over rows j..b
                W = data.u[j - 1:b] @ G.T + y[j:b + 1] @ K.T
                xf[j:b + 1] = propagate(F, x, W)
                xp[j:b + 1] = xf[j - 1:b] @ Phi.T + data.u[j - 1:b] @ Gam.T
                e[j:b + 1] = y[j:b + 1] - xp[j:b + 1] @ C.T
                S[j:b + 1] = C @ Pss @ C.T + R
                x = xf[b]
                P = Pss - K @ (C @ Pss @ C.T + R) @ K.T
    return Filtered(e, S, xp, xf, gaussian_loglik(e, S))


def gaussian_loglik(e: np.ndarray, S: np.ndarray) -> float:
    """Σ_k −½ (p log 2π + log det S_k + e_kᵀ S_k⁻¹ e_k) over innovations ``e`` (rows × p) with covariances ``S``
    (rows × p × p); −inf where it is not finite."""
    p = e.shape[1]
    if p == 1:
        s = S[:, 0, 0]
        loglik = -0.5 * float(np.sum(LOG_2PI + np.log(s) + e[:, 0] ** 2 / s))
    else:
        sign, logdet = np.linalg.slogdet(S)
        quad = np.einsum("ki,ki->k", e, np.linalg.solve(S, e[..., None])[..., 0])
        loglik = -0.5 * float(np.sum(p * LOG_2PI + logdet + quad))
    return loglik if np.isfinite(loglik) else -np.inf


def k_step(system: System, data: Series, filtered: Filtered, k: int) -> np.ndarray:
    """Output predictions k samples ahead (rows × p): row j holds ŷ_j|j−k, the filtered state at row j − k run
    forward open loop with the measured inputs (NaN for the first k rows). Inputs are known (weather, heating):
    only the state, not the future, comes from the measurements."""
    N = len(data)
    out = np.full((N, len(system.C)), np.nan)
    if k < 1 or k >= N:
        return out
    levels, dts = data.steps()
    keys = list(zip(levels.tolist(), dts.tolist()))
    mats = {key: system.discrete(*key)[:2] for key in set(keys)}
    index = {key: i for i, key in enumerate(mats)}
    Phis = np.stack([mats[key][0] for key in index])
    Gams = np.stack([mats[key][1] for key in index])
    step_of = np.array([index[key] for key in keys])  # step j−1 → j
    X = filtered.x_filt[:N - k].copy()  # origins j − k for targets j = k..N−1
    for i in range(k):
        rows = np.arange(i, N - k + i)  # the step from row rows to rows + 1
        s = step_of[rows]
        X = np.einsum("kab,kb->ka", Phis[s], X) + np.einsum("kab,kb->ka", Gams[s], data.u[rows])
    out[k:] = X @ system.C.T + data.u[k:] @ system.D.T
    return out


def simulate(system: System, data: Series, seed: int, x0: np.ndarray | None = None) -> np.ndarray:
    """A sample path of the SDE at the sample times of ``data`` (its inputs; its outputs are ignored except for
    the default start): outputs with measurement noise (rows × p). Exact in distribution (the discrete steps)."""
    rng = np.random.default_rng(seed)
    N, n = len(data), system.n_states
    x = initial_state(system, data) if x0 is None else np.asarray(x0, dtype=float)
    X = np.empty((N, n))
    X[0] = x
    if N > 1:
        levels, dts = data.steps()
        cache: dict[tuple, tuple] = {}
        for j in range(1, N):
            key = (int(levels[j - 1]), float(dts[j - 1]))
            if key not in cache:
                Phi, Gam, Q = system.discrete(*key)
                cache[key] = (Phi, Gam, np.linalg.cholesky(Q))
            Phi, Gam, L = cache[key]
            x = Phi @ x + Gam @ data.u[j - 1] + L @ rng.standard_normal(n)
            X[j] = x
    return X @ system.C.T + data.u @ system.D.T + rng.standard_normal((N, len(system.C))) * system.r
