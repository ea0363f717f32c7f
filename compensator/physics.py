"""Runtime ``lptn``: the calibrated thermal network's state observer and its linear read-out (``lptn``,
``lptn_hybrid``).

The network is linear at each spindle-speed level (speed rounded to 10 rpm, as the model does): the package
tabulates dT/dt = A(n)·T + B(n)·[1, T_ambient, T_coolant] over the levels from 0 rpm to twice the training
maximum. Per row the observer steps the node temperatures with the exact discretisation at the row's time step
(matrix exponential) corrected by a steady-state Kalman gain (discrete algebraic Riccati equation), both cached
per (level, step); displacement (µm) = x·W_x + T·W_T + ambient·w_ambient + c. scipy does both matrix functions.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm, solve_discrete_are

from thermodrift.compensator.runtime import Base


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
            A, B = self.matrices(speed_rpm)
            N, M = B.shape
            aug = np.zeros((N + M, N + M))
            aug[:N, :N], aug[:N, N:] = A * dt_s, B * dt_s
            E = expm(aug)
            Phi, Gam = E[:N, :N], E[:N, N:]
            if len(self.C):
                P = solve_discrete_are(Phi.T, self.C.T, np.diag(self.q * dt_s) + 1e-12 * np.eye(N), self.R)
                K = P @ self.C.T @ np.linalg.inv(self.C @ P @ self.C.T + self.R)
            else:
                K = np.zeros((N, 0))
            IKC = np.eye(N) - K @ self.C
            F, G = IKC @ Phi, IKC @ Gam
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
