"""Linear stochastic differential equations and their exact discretisation.

dx = (A x + B u) dt + diag(σ) dW,  y_k = C x(t_k) + D u_k + e_k,  e_k ~ N(0, diag(r²)),

with the input held over each sample step (zero-order hold). A system may have several operating *levels* (the
machine-tool networks: one (A, B) per spindle-speed level; a building has one): ``A`` is levels × n × n and
``B`` levels × n × m, and each sample names the level that holds over the step that follows it.

The step of length Δ is exact: (Φ, Γ) from one matrix exponential of [[A, B], [0, 0]]Δ (the compensator's
:func:`~thermodrift.compensator.physics.exact_step`) and the process-noise covariance
Q_Δ = ∫₀^Δ e^{As} Σ e^{Aᵀs} ds, Σ = diag(σ²), by Van Loan's method: with M = [[−A, Σ], [0, Aᵀ]]Δ and
E = e^M, Φ = E₂₂ᵀ and Q_Δ = Φ E₁₂. Van Loan's block grows as e^{|λ|Δ} for a fast mode λ and loses every digit (or
overflows) on a stiff system, e.g. a fast sensor or heater state; where A is stable and some |λ|Δ exceeds ``STIFF``,
Q_Δ = P − Φ P Φᵀ instead, with P the stationary covariance (A P + P Aᵀ + Σ = 0, scipy's Lyapunov solver).
Units: whatever time unit A is in (``time_unit_s`` seconds); σ in state units per √(time unit), r in output
units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm, expm_frechet, solve_continuous_lyapunov

from thermodrift.compensator.physics import exact_step

STIFF = 10.0  # |λ|Δ above which the step's noise covariance comes from the Lyapunov equation


@dataclass(frozen=True)
class System:
    """One parameter vector's matrices (see the module docstring). ``A`` (L, n, n), ``B`` (L, n, m), ``C`` (p, n),
    ``D`` (p, m), ``sigma`` (n,) process-noise intensity per state, ``r`` (p,) measurement standard deviation
    per output."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    sigma: np.ndarray
    r: np.ndarray

    @property
    def n_states(self) -> int:
        return self.A.shape[1]

    @property
    def R(self) -> np.ndarray:
        """Measurement covariance, diag(r²)."""
        return np.diag(self.r ** 2)

    def discrete(self, level: int, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Φ, Γ, Q_Δ) of one level over a step ``dt`` (exact, see the module docstring)."""
        A, B = self.A[level], self.B[level]
        Phi, Gam = exact_step(A, B, dt)
        n = len(A)
        lam = np.linalg.eigvals(A)
        if lam.real.max() < 0 and np.abs(lam).max() * dt > STIFF:
            P = solve_continuous_lyapunov(A, -np.diag(self.sigma ** 2))
            Q = P - Phi @ P @ Phi.T
            return Phi, Gam, 0.5 * (Q + Q.T) + 1e-14 * np.eye(n)
        M = np.zeros((2 * n, 2 * n))
        M[:n, :n], M[:n, n:], M[n:, n:] = -A * dt, np.diag(self.sigma ** 2) * dt, A.T * dt
        E = expm(M)
        Q = Phi @ E[:n, n:]
        return Phi, Gam, 0.5 * (Q + Q.T) + 1e-14 * np.eye(n)

    def discrete_derivatives(self, level: int, dt: float, dA: np.ndarray, dB: np.ndarray, dsigma: np.ndarray):
        """(Φ, Γ, Q_Δ) of :meth:`discrete` and their derivatives (k × …) along k directions (dA: k × n × n, dB:
        k × n × m, dsigma: k × n): Fréchet derivatives of the same matrix exponentials (scipy's ``expm_frechet``);
        on the stiff branch the Lyapunov equation differentiated, A dP + dP Aᵀ = −(dA P + P dAᵀ + dΣ), and
        dQ = dP − dΦ P Φᵀ − Φ dP Φᵀ − Φ P dΦᵀ."""
        Phi, Gam, Q = self.discrete(level, dt)
        A, B = self.A[level], self.B[level]
        n, m, k = len(A), B.shape[1], len(dA)
        aug = np.zeros((n + m, n + m))
        aug[:n, :n], aug[:n, n:] = A * dt, B * dt
        dPhi, dGam, dQ = np.empty((k, n, n)), np.empty((k, n, m)), np.empty((k, n, n))
        dSig = np.einsum("ij,kj->kij", np.eye(n), 2.0 * self.sigma * dsigma)
        daug = np.zeros((n + m, n + m))
        for i in range(k):
            daug[:n, :n], daug[:n, n:] = dA[i] * dt, dB[i] * dt
            L = expm_frechet(aug, daug, compute_expm=False, check_finite=False)
            dPhi[i], dGam[i] = L[:n, :n], L[:n, n:]
        lam = np.linalg.eigvals(A)
        if lam.real.max() < 0 and np.abs(lam).max() * dt > STIFF:
            P = solve_continuous_lyapunov(A, -np.diag(self.sigma ** 2))
            rhs = dA @ P
            rhs = rhs + np.swapaxes(rhs, 1, 2) + dSig
            lyap = np.kron(A, np.eye(n)) + np.kron(np.eye(n), A)  # A X + X Aᵀ on row-major vec(X)
            dP = -np.linalg.solve(lyap, rhs.reshape(k, -1).T).T.reshape(k, n, n)
            T = dPhi @ (P @ Phi.T)
            dQ = dP - T - np.swapaxes(T, 1, 2) - Phi @ dP @ Phi.T
        else:
            M = np.zeros((2 * n, 2 * n))
            M[:n, :n], M[:n, n:], M[n:, n:] = -A * dt, np.diag(self.sigma ** 2) * dt, A.T * dt
            E = expm(M)
            dM = np.zeros((2 * n, 2 * n))
            for i in range(k):
                dM[:n, :n], dM[:n, n:], dM[n:, n:] = -dA[i] * dt, dSig[i] * dt, dA[i].T * dt
                dE = expm_frechet(M, dM, compute_expm=False, check_finite=False)
                dQ[i] = dPhi[i] @ E[:n, n:] + Phi @ dE[:n, n:]
        return Phi, Gam, Q, dPhi, dGam, 0.5 * (dQ + np.swapaxes(dQ, 1, 2))

    def steady_state(self, level: int, u: np.ndarray) -> np.ndarray:
        """The equilibrium state at constant input ``u`` (least squares where A is singular)."""
        return np.linalg.lstsq(self.A[level], -self.B[level] @ u, rcond=None)[0]

    def static_gain(self, level: int = 0) -> np.ndarray:
        """Steady-state gain from inputs to outputs, −C A⁻¹ B + D (p × m)."""
        return -self.C @ np.linalg.solve(self.A[level], self.B[level]) + self.D


@dataclass(frozen=True)
class Series:
    """Data for the filter: times ``t`` (rows, in the model's time unit), inputs ``u`` (rows × m), outputs ``y``
    (rows × p) and the level of each row (``level``; zeros for a single-level system)."""

    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    level: np.ndarray

    @classmethod
    def of(cls, t, u, y, level=None) -> "Series":
        t = np.asarray(t, dtype=float)
        u = np.asarray(u, dtype=float).reshape(len(t), -1)
        y = np.asarray(y, dtype=float).reshape(len(t), -1)
        lev = np.zeros(len(t), dtype=int) if level is None else np.asarray(level, dtype=int)
        return cls(t, u, y, lev)

    def __len__(self) -> int:
        return len(self.t)

    def rows(self, a: int, b: int) -> "Series":
        """Rows a..b−1."""
        return Series(self.t[a:b], self.u[a:b], self.y[a:b], self.level[a:b])

    def steps(self) -> tuple[np.ndarray, np.ndarray]:
        """Per row j ≥ 1 the key of the step that reaches it: (level of row j−1, Δt rounded to 1e-9)."""
        return self.level[:-1], np.round(np.diff(self.t), 9)
