"""The gradient of the Kalman filter's innovations log-likelihood (:func:`.kalman.run`) by forward sensitivities,
in one pass beside the filter: what lets the maximum-likelihood search (:func:`.fit.fit`) take one filter pass per
gradient instead of the k + 1 of finite differences (k parameters).

Per parameter θ_i the pass carries the derivatives of everything the filter computes: the exact step (Φ, Γ, Q_Δ;
:meth:`.sde.System.discrete_derivatives`), the stationary filter's covariance (the derivative of the discrete
algebraic Riccati equation P = Φ̄ P Φ̄ᵀ + L R Lᵀ + Q, with L = Φ K the predictor gain and Φ̄ = Φ − L C: by
stationarity in L, dP − Φ̄ dP Φ̄ᵀ = (dΦ − L dC) P Φ̄ᵀ + Φ̄ P (dΦ − L dC)ᵀ + L dR Lᵀ + dQ, a discrete Lyapunov
equation), the time-varying rows (the derivative of each prediction and update), and the stationary rows (a linear
recursion with the stationary filter's own matrix F, run for all parameters at once in F's Schur basis). The log-
likelihood's derivative per row is −½ (tr S⁻¹dS + 2 aᵀde − aᵀ dS a), a = S⁻¹e.

The system's matrices and the initial state as functions of the parameters come from the model (any
:class:`~.fit.Model`): their derivatives are central differences of ``model.system`` and of
:func:`.kalman.initial_state` (cheap: no filter; rational functions of the parameters, so the error is about
1e-10 relative); everything downstream is analytic. The function value is the one :func:`.kalman.run` returns
(the same operations in the same order). :func:`scores` gives the same gradient row by row (the stationary rows
that end the series then run forward, not by the adjoint).

Why by hand: torch's autograd would differentiate the matrix exponential, but neither the Riccati solution nor the
thousands of stationary rows (a sequential recursion, run in C by ``lfilter`` here) fit its graph at a useful cost.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.linalg import schur
from scipy.signal import lfilter

from thermodrift.compensator.physics import kalman_update, steady_filter
from thermodrift.core.physics.integrate import propagate
from thermodrift.core.physics.stochastic.kalman import gaussian_loglik, initial_state
from thermodrift.core.physics.stochastic.sde import Series, System

STEP = 1e-5  # central-difference step on the search scale η for the system matrices and the initial state


@dataclass(frozen=True)
class Derivatives:
    """Derivatives of a system's matrices along k parameters: ``A`` (k, L, n, n), ``B`` (k, L, n, m), ``C`` (k, p,
    n), ``D`` (k, p, m), ``sigma`` (k, n), ``r`` (k, p) and the initial state ``x0`` (k, n)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    sigma: np.ndarray
    r: np.ndarray
    x0: np.ndarray


def derivatives(system_at: Callable[[np.ndarray], System], eta: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                data: Series, init_rows: int) -> Derivatives:
    """Central differences along each η_i (one-sided where η_i is on its bound) of the system and the initial
    state."""
    k = len(eta)
    parts: list[list[np.ndarray]] = [[] for _ in range(7)]
    for i in range(k):
        up, dn = eta.copy(), eta.copy()
        up[i], dn[i] = min(eta[i] + STEP, hi[i]), max(eta[i] - STEP, lo[i])
        h = up[i] - dn[i]
        a, b = system_at(up), system_at(dn)
        xa, xb = initial_state(a, data, init_rows), initial_state(b, data, init_rows)
        for out, va, vb in zip(parts, (a.A, a.B, a.C, a.D, a.sigma, a.r, xa), (b.A, b.B, b.C, b.D, b.sigma, b.r, xb)):
            out.append((va - vb) / h)
    return Derivatives(*(np.array(p) for p in parts))


def _T(X: np.ndarray) -> np.ndarray:
    return np.swapaxes(X, -1, -2)


def steady_derivatives(Phi, Gam, C, Q, R, dPhi, dGam, dC, dQ, dR, steady):
    """Derivatives (dF, dG, dK, dP) of :func:`~thermodrift.compensator.physics.steady_filter`'s (F, G, K, P)."""
    F, G, K, P = steady
    n = len(Phi)
    S = C @ P @ C.T + R
    Sinv = np.linalg.inv(S)
    L = Phi @ K
    Pbar = Phi - L @ C
    X = dPhi - L @ dC
    H = X @ (P @ Pbar.T)
    H = H + _T(H) + L @ dR @ L.T + dQ
    M = np.eye(n * n) - np.kron(Pbar, Pbar)
    dP = np.linalg.solve(M, H.reshape(len(H), -1).T).T.reshape(H.shape)
    dP = 0.5 * (dP + _T(dP))
    CP = C @ P
    dS = dC @ CP.T + C @ dP @ C.T + CP @ _T(dC) + dR
    dK = (dP @ C.T + P @ _T(dC)) @ Sinv - K @ dS @ Sinv
    IKC = np.eye(n) - K @ C
    dIKC = -(dK @ C + K @ dC)
    return dIKC @ Phi + IKC @ dPhi, dIKC @ Gam + IKC @ dGam, dK, dP


def _propagate_many(F: np.ndarray, dx0: np.ndarray, dW: np.ndarray) -> np.ndarray:
    """x_{r} = F x_{r−1} + dW[:, r] for each of k sequences at once (dx0: k × n, dW: k × rows × n) → k × rows × n;
    the Schur-basis recursion of :func:`~thermodrift.core.physics.integrate.propagate`, one ``lfilter`` call per
    mode over all k sequences."""
    k, rows, n = dW.shape
    if rows < 64:
        out = np.empty_like(dW)
        x = dx0
        for r in range(rows):
            x = x @ F.T + dW[:, r]
            out[:, r] = x
        return out
    Rs, Qs = schur(F, output="complex", check_finite=False)
    z0 = dx0 @ Qs.conj()                        # k × n
    V = dW @ Qs.conj()                          # k × rows × n
    Z = np.empty((k, rows + 1, n), dtype=complex)
    Z[:, 0] = z0
    for i in range(n - 1, -1, -1):
        v = V[:, :, i] + Z[:, :-1, i + 1:] @ Rs[i, i + 1:] if i < n - 1 else V[:, :, i]
        lam = Rs[i, i]
        Z[:, 1:, i], _ = lfilter([1.0], [1.0, -lam], v, axis=1, zi=(lam * z0[:, i])[:, None])
    return (Z[:, 1:] @ Qs.T).real


def _stationary_adjoint(Phi, F, K, C, A_, xf, xp, u, y, dx, dPhi, dGam, dF, dG, dK, dC, dD) -> np.ndarray:
    """−Σ_r a_rᵀ de_r over the stationary rows j..b that end the series, by the adjoint of x_r = F x_{r−1} + w_r:
    λ_t = Φᵀ Cᵀ a_{t+1} + Fᵀ λ_{t+1} (λ_b = 0), one backward recursion, so each parameter costs a few n × n
    contractions with sums over the rows instead of its own recursion. ``xf``: filtered states of rows j−1..b,
    ``xp`` predicted states of rows j..b, ``u`` inputs of rows j−1..b, ``y`` outputs (less D u) of rows j..b,
    ``dx`` the state derivative at row j−1."""
    Bm = A_ @ C                                  # rows × n: b_r = Cᵀ a_r
    c = Bm @ Phi                                 # c_r = Φᵀ b_r
    lam = propagate(F.T, np.zeros(len(F)), c[::-1])[::-1]  # λ_{j−1} … λ_{b−1}
    lt = lam[1:]                                 # λ_t, t = j … b−1, against w_t
    g = dx @ lam[0]
    g += np.einsum("kab,ab->k", dF, lt.T @ xf[:-2]) + np.einsum("kab,ab->k", dG, lt.T @ u[:-2])
    g += np.einsum("kab,ab->k", dK, lt.T @ y[:-1]) - np.einsum("kpm,pm->k", dD, K.T @ lt.T @ u[1:-1])
    g += np.einsum("kpn,pn->k", dC, A_.T @ xp) + np.einsum("kab,ab->k", dPhi, Bm.T @ xf[:-1])
    g += np.einsum("kab,ab->k", dGam, Bm.T @ u[:-1]) + np.einsum("kpm,pm->k", dD, A_.T @ u[1:])
    return g


def run(system: System, d: Derivatives, data: Series, **options) -> tuple[float, np.ndarray]:
    """(log-likelihood, its gradient along the k parameters of ``d``) of :func:`.kalman.run` over ``data``."""
    loglik, grad, _ = _pass(system, d, data, per_row=False, **options)
    return loglik, grad


def scores(system: System, d: Derivatives, data: Series, **options) -> np.ndarray:
    """Each row's term of the gradient (rows × k), the scores; they sum to :func:`run`'s gradient."""
    return _pass(system, d, data, per_row=True, **options)[2]


def _pass(system: System, d: Derivatives, data: Series, *, per_row: bool, p0: float = 1.0, init_rows: int = 96,
          tol: float = 1e-9, transient: int = 200) -> tuple[float, np.ndarray, np.ndarray | None]:
    C, D, R = system.C, system.D, system.R
    N, n, p = len(data), system.n_states, len(C)
    k = len(d.x0)
    dR = np.einsum("ij,kj->kij", np.eye(p), 2.0 * system.r * d.r)
    u = data.u
    y = data.y - u @ D.T
    dy = -np.einsum("rm,kpm->krp", u, d.D)               # k × rows × p
    e = np.empty((N, p))
    S = np.empty((N, p, p))
    grad = np.zeros(k)
    per = np.zeros((N, k)) if per_row else None  # the scores, row by row

    read_fixed = not d.C.any()  # the read-out does not move with the parameters (every RC network): fewer terms

    def update(x, dx, P, dP, j):  # one time-varying measurement update with its derivatives (row j)
        e[j] = y[j] - C @ x
        CP = C @ P
        if read_fixed:
            de = dy[:, j] - dx @ C.T
            dCP = C @ dP
            dS = dCP @ C.T + dR
        else:
            de = dy[:, j] - d.C @ x - dx @ C.T
            dCP = d.C @ P + C @ dP
            dS = dCP @ C.T + CP @ _T(d.C) + dR
        x_new, Pf, S[j] = kalman_update(x, P, e[j], C, R)
        Sinv = np.linalg.inv(S[j])
        K = CP.T @ Sinv
        dK = _T(dCP) @ Sinv - K @ dS @ Sinv
        dx_new = dx + dK @ e[j] + de @ K.T
        T2 = dK @ (S[j] @ K.T)
        dPf = dP - T2 - _T(T2) - K @ dS @ K.T
        a = Sinv @ e[j]
        g = -0.5 * (np.einsum("ij,kji->k", Sinv, dS) + 2.0 * de @ a - np.einsum("i,kij,j->k", a, dS, a))
        return x_new, dx_new, Pf, dPf, g

    x = initial_state(system, data, init_rows)
    dx = d.x0
    P = np.eye(n) * p0 ** 2
    dP = np.zeros((k, n, n))
    x, dx, P, dP, g = update(x, dx, P, dP, 0)
    grad += g
    if per_row:
        per[0] = g
    if N > 1:
        levels, dts = data.steps()
        change = np.flatnonzero((levels[1:] != levels[:-1]) | (dts[1:] != dts[:-1])) + 1
        cache: dict[tuple, tuple] = {}
        for a, b in zip(np.r_[0, change], np.r_[change, N - 1]):
            key = (int(levels[a]), float(dts[a]))
            if key not in cache:
                lev = key[0]
                Phi, Gam, Q, dPhi, dGam, dQ = system.discrete_derivatives(lev, key[1], d.A[:, lev], d.B[:, lev],
                                                                          d.sigma)
                steady = steady_filter(Phi, Gam, C, Q, R)
                cache[key] = (Phi, Gam, Q, dPhi, dGam, dQ, steady,
                              steady_derivatives(Phi, Gam, C, Q, R, dPhi, dGam, d.C, dQ, dR, steady))
            Phi, Gam, Q, dPhi, dGam, dQ, (F, G, K, Pss), (dF, dG, dK, dPss) = cache[key]
            j = a + 1
            while j <= b and j <= transient:
                dx = dPhi @ x + dx @ Phi.T + dGam @ u[j - 1]
                x = Phi @ x + Gam @ u[j - 1]
                T1 = dPhi @ (P @ Phi.T)
                dP = T1 + _T(T1) + Phi @ dP @ Phi.T + dQ
                P = Phi @ P @ Phi.T + Q
                done = np.abs(P - Pss).max() <= tol * np.abs(Pss).max()
                x, dx, P, dP, g = update(x, dx, P, dP, j)
                grad += g
                if per_row:
                    per[j] = g
                j += 1
                if done:
                    break
            if j <= b:
                W = u[j - 1:b] @ G.T + y[j:b + 1] @ K.T
                xf = np.empty((b - j + 2, n))
                xf[0] = x
                xf[1:] = propagate(F, x, W)
                xp = xf[:-1] @ Phi.T + u[j - 1:b] @ Gam.T
                e[j:b + 1] = y[j:b + 1] - xp @ C.T
                Sj = C @ Pss @ C.T + R
                S[j:b + 1] = Sj
                CP = C @ Pss
                dSj = d.C @ CP.T + C @ dPss @ C.T + CP @ _T(d.C) + dR
                Sinv = np.linalg.inv(Sj)
                A_ = e[j:b + 1] @ Sinv                 # rows × p: a_r = S⁻¹ e_r (S symmetric)
                rows = b + 1 - j
                grad += -0.5 * rows * np.einsum("ij,kji->k", Sinv, dSj) + 0.5 * np.einsum("ij,kij->k", A_.T @ A_, dSj)
                if per_row:
                    per[j:b + 1] = (-0.5 * np.einsum("ij,kji->k", Sinv, dSj)
                                    + 0.5 * np.einsum("ri,kij,rj->rk", A_, dSj, A_))
                if b == N - 1 and not per_row:  # the last rows: −Σ a_rᵀ de_r by the adjoint recursion (no state derivative needed after)
                    grad += _stationary_adjoint(Phi, F, K, C, A_, xf, xp, u[j - 1:b + 1], y[j:b + 1], dx, dPhi, dGam,
                                                dF, dG, dK, d.C, d.D)
                    continue
                dW = (xf[:-1] @ _T(dF) + u[j - 1:b] @ _T(dG) + y[j:b + 1] @ _T(dK) + dy[:, j:b + 1] @ K.T)
                dxf = np.empty((k, b - j + 2, n))
                dxf[:, 0] = dx
                dxf[:, 1:] = _propagate_many(F, dx, dW)
                dxp = xf[:-1] @ _T(dPhi) + dxf[:, :-1] @ Phi.T + u[j - 1:b] @ _T(dGam)
                de = dy[:, j:b + 1] - xp @ _T(d.C) - dxp @ C.T
                grad -= np.einsum("rp,krp->k", A_, de)
                if per_row:
                    per[j:b + 1] -= np.einsum("rp,krp->rk", A_, de)
                x, dx = xf[-1], dxf[:, -1]
                T2 = dK @ (Sj @ K.T)
                dP = dPss - T2 - _T(T2) - K @ dSj @ K.T
                P = Pss - K @ Sj @ K.T
    loglik = gaussian_loglik(e, S)
    if not np.isfinite(loglik):
        return -np.inf, np.zeros(k), per
    return loglik, grad, per
