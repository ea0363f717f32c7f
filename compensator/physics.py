"""Runtime ``lptn``: the calibrated thermal network's state observer and its linear read-out (``lptn``,
``lptn_hybrid``).

The network is linear at each spindle-speed level (speed rounded to 10 rpm, as the model does): the package
tabulates dT/dt = A(n)·T + B(n)·[1, T_ambient, T_coolant] over the levels from 0 rpm to twice the training
maximum. Per row the observer steps the node temperatures with the exact discretisation at the row's time step
(matrix exponential) corrected by a steady-state Kalman gain (discrete algebraic Riccati equation), both cached
per (level, step); displacement (µm) = x·W_x + T·W_T + ambient·w_ambient + c. scipy does both matrix functions.

This module is the project's one home of the Kalman step (the compensator is the lowest layer, so the framework
imports it from here): :func:`exact_step` (zero-order-hold discretisation), :func:`steady_filter` (the stationary
gain and the filtered-state recursion) and :func:`kalman_update` (one time-varying measurement update), used by
this runtime, ``core.physics.calibration.StateObserver`` and the stochastic grey-box engine
(``core.physics.stochastic``).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm, solve_discrete_are

from thermodrift.compensator.runtime import Base


def exact_step(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(Φ, Γ) of dx/dt = A x + B u over a step ``dt`` (A's time unit) with u held: one matrix exponential of the
    augmented matrix [[A, B], [0, 0]]·dt."""
    N, M = B.shape
    aug = np.zeros((N + M, N + M))
    aug[:N, :N], aug[:N, N:] = A * dt, B * dt
    E = expm(aug)
    return E[:N, :N], E[:N, N:]


def steady_filter(Phi: np.ndarray, Gam: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The stationary Kalman filter of x_k = Φ x_{k−1} + Γ u_{k−1} + w (cov Q), y_k = C x_k + v (cov R):
    (F, G, K, P) with the filtered state x_k = F x_{k−1} + G u_{k−1} + K y_k, F = (I − KC)Φ, G = (I − KC)Γ,
    K = P Cᵀ (C P Cᵀ + R)⁻¹ and P the predicted-state covariance (discrete algebraic Riccati equation).
    Without measurements (C has no row) K is empty and P is None."""
    N = len(Phi)
    if len(C):
        P = solve_discrete_are(Phi.T, C.T, Q, R)
        K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    else:
        P, K = None, np.zeros((N, 0))
    IKC = np.eye(N) - K @ C
    return IKC @ Phi, IKC @ Gam, K, P


def kalman_update(x: np.ndarray, P: np.ndarray, e: np.ndarray, C: np.ndarray, R: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One measurement update of a predicted state ``x`` with covariance ``P`` by the innovation ``e`` = y − C x
    (− D u): (filtered x, filtered P, innovation covariance S = C P Cᵀ + R)."""
    S = C @ P @ C.T + R
    K = np.linalg.solve(S, C @ P).T
    return x + K @ e, P - K @ S @ K.T, S


class Runtime(Base):
    """State: column names (``temperature_columns``, ``speed_column``, ``ambient_column`` or None), the level
    table (``speed_step_rpm``, ``A`` levels × N × N in 1/s, ``B`` levels × N × 3), the observer (``C``,
    ``offsets`` K, ``R`` K², ``q`` K²/s) and the read-out (``W_x``, ``W_T`` or None, ``w_ambient`` or None,
    ``c``), ``ambient_default_degC`` when no ambient column is used."""

    def __init__(self, state):
        super().__init__(state)
        pos = {c: i for i, c in enumerate(self.inputs)}
        self.t_idx = np.array([pos[c] for c in state["temperature_columns"]], dtype=int)
        self.s_idx = pos[state["speed_column"]]
        amb = state.get("ambient_column")
        self.a_idx = pos[amb] if amb else None
        self.ambient_default = float(state.get("ambient_default_degC", 20.0))
        self.step_rpm = float(state["speed_step_rpm"])
        self.A, self.B = np.asarray(state["A"], dtype=float), np.asarray(state["B"], dtype=float)
        self.C, self.offsets = np.asarray(state["C"], dtype=float), np.asarray(state["offsets"], dtype=float)
        self.R, self.q = np.asarray(state["R"], dtype=float), np.asarray(state["q"], dtype=float)
        self.W_x, self.c = np.asarray(state["W_x"], dtype=float), np.asarray(state["c"], dtype=float)
        self.W_T = None if state.get("W_T") is None else np.asarray(state["W_T"], dtype=float)
        self.w_ambient = None if state.get("w_ambient") is None else np.asarray(state["w_ambient"], dtype=float)
        self.max_speed_rpm = self.step_rpm * (len(self.A) - 1)
        self._levels: dict[tuple[float, float], np.ndarray] = {}
        self._pinv = np.linalg.pinv(self.C) if len(self.C) else None

    def matrices(self, speed_rpm: float) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) at a speed level; speeds beyond the table take its last level (the input checks flag them)."""
        k = min(int(round(speed_rpm / self.step_rpm)), len(self.A) - 1)
        return self.A[k], self.B[k]

    def row_matrix(self, speed_rpm: float, dt_s: float) -> np.ndarray:
        """[F | K | G₀ − K·offsets | G_ambient | G_coolant] of one (level, step), cached."""
        key = (speed_rpm, dt_s)
        hit = self._levels.get(key)
        if hit is None:
            Phi, Gam = exact_step(*self.matrices(speed_rpm), dt_s)
            N = len(Phi)
            F, G, K, _ = steady_filter(Phi, Gam, self.C, np.diag(self.q * dt_s) + 1e-12 * np.eye(N), self.R)
            hit = self._levels[key] = np.hstack([F, K, (G[:, 0] - K @ self.offsets)[:, None], G[:, 1:3]])
        return hit

    def start(self, ambient: float, temps: np.ndarray) -> np.ndarray:
        """Node temperatures at a first row: at rest in equilibrium with ambient, observed nodes at the readings."""
        A, B = self.matrices(0.0)
        u = np.zeros(B.shape[1])
        u[0], u[1], u[2] = 1.0, ambient, ambient
        x = np.linalg.solve(A, -B @ u)
        if self._pinv is not None:
            x = x + self._pinv @ (temps - self.offsets - self.C @ x)
        return x

    def streamer(self, history=None, times_s=None) -> "Streamer":
        return self.warm(Streamer(self), history, times_s)


class Streamer:
    def __init__(self, rt: Runtime):
        self.rt = rt
        self.x: np.ndarray | None = None
        self.last: tuple[float, float, float] | None = None  # time s, speed rpm, ambient °C of the last row

    def update(self, values: np.ndarray, t_s: float | None = None) -> np.ndarray:
        rt = self.rt
        if t_s is None:
            raise ValueError("a physics runtime steps its state by time: pass t_s")
        temps = values[rt.t_idx]
        speed = round(max(float(values[rt.s_idx]), 0.0) / 10.0) * 10.0
        ambient = float(values[rt.a_idx]) if rt.a_idx is not None else rt.ambient_default
        if self.x is None:
            self.x = rt.start(ambient, temps)
        else:
            t0, sp0, amb0 = self.last
            M = rt.row_matrix(sp0, round(t_s - t0, 9))
            self.x = M @ np.concatenate([self.x, temps, [1.0, amb0, amb0]])
        self.last = (float(t_s), speed, ambient)
        out = self.x @ rt.W_x + rt.c
        if rt.W_T is not None:
            out = out + temps @ rt.W_T
        if rt.w_ambient is not None:
            out = out + ambient * rt.w_ambient
        return out
