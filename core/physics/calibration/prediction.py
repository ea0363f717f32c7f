"""Predicting with a calibrated network: open-loop simulation (:func:`predict`) and a state observer that
corrects the simulated state with the measured temperatures (:class:`StateObserver`), as a controller runs it.

The observer is a steady-state Kalman filter over the network, per operating level (speed, coolant flow, step):
x⁻ = Φ x + Γ u (the engine's step matrices, inputs held over the step), x = x⁻ + K (y − offsets − C x⁻), where
C maps nodes to the temperature sensors it uses (lag-free sensors reading nodes), K the stationary gain of the
discrete Riccati equation (the compensator's Kalman step, :func:`thermodrift.compensator.physics.steady_filter`)
with measurement noise σ² per sensor and process noise ``process_K²·dt/τ`` per node (``τ`` the node's own time
constant C/ΣG, so ``process_K`` is the model error over one time constant). Unobserved nodes (the auto network's
hidden nodes) run open loop. Over a block of steps at one level the filter is linear and time-invariant, so a
batch runs through the engine's propagator (:func:`integrate.propagate`) and a single row is one matrix-vector
step — both give the same numbers to rounding.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from thermodrift.compensator.physics import steady_filter
from thermodrift.core.physics.integrate import CompiledNetwork, propagate
from thermodrift.core.physics.network import Network, TemperatureSensor
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.physics.sensors import temperature_reading


def predict(network: Network, scenario: Scenario, initial: np.ndarray | None = None,
            reference: np.ndarray | None = None) -> tuple[pd.DataFrame, np.ndarray]:
    """Noise-free sensor readings (°C, µm, with the network's offsets and lags) over ``scenario`` and the node
    temperatures (°C, K × N), simulated open loop.

    ``initial``: node temperatures at the first sample (default: rest). Displacements are relative to the node
    temperatures ``reference`` (default: the initial state).
    """
    comp = CompiledNetwork(network)
    X = comp.trajectory(scenario, initial="steady" if initial is None else initial)
    idx = comp.index
    t = scenario.time_s
    bnd = {"ambient": scenario.frame["ambient_degC"].to_numpy(),
           "coolant": scenario.frame["coolant_inlet_degC"].to_numpy()}
    Y = comp.displacements(X, scenario.frame["speed_rpm"].to_numpy(),
                           None if reference is None else np.asarray(reference, dtype=float))
    cols = {}
    for s in network.sensors:
        if isinstance(s, TemperatureSensor):
            cols[s.name] = temperature_reading(s, {n: X[:, idx[n]] if n in idx else bnd[n] for n in s.weights}, t)
        else:
            cols[s.name] = Y[:, [o.name for o in network.outputs].index(s.output)] + s.offset_um
    return pd.DataFrame(cols, index=pd.Index(t, name="time_s")), X


class StateObserver:
    """Steady-state Kalman filter over ``network`` using the temperature sensors named in ``sensors``
    (lag-free, reading nodes); see the module docstring. ``noise_K`` and ``process_K``: per sensor / per node
    standard deviations (K); missing entries take 0.01 K and 0.1 K. Networks with signal-driven sources
    (cutting power, axis velocity) are not supported: the observer takes speed, ambient and coolant only.

    State: :attr:`x` (node temperatures, °C) after the last row, ``None`` before the first (and after
    :meth:`reset`).
    """

    def __init__(self, network: Network, sensors: Sequence[str], noise_K: Mapping[str, float] | None = None,
                 process_K: Mapping[str, float] | None = None):
        self.comp = CompiledNetwork(network)
        if self.comp.signal_sources:
            raise ValueError("the state observer takes speed, ambient and coolant inputs only; this network has "
                             "signal-driven sources")
        by_name = {s.name: s for s in network.temperature_sensors}
        idx = self.comp.index
        self.sensors = [by_name[s] for s in sensors]
        bad = [s.name for s in self.sensors if s.lag_s > 0 or any(n not in idx for n in s.weights)]
        if bad:
            raise ValueError(f"sensors {bad} lag or read a boundary; the observer needs lag-free node sensors")
        N = len(self.comp.names)
        self.C = np.zeros((len(self.sensors), N))
        for r, s in enumerate(self.sensors):
            for n, w in s.weights.items():
                self.C[r, idx[n]] += w
        self.offsets = np.array([s.offset_K for s in self.sensors])
        self.R = np.diag([max((noise_K or {}).get(s.name, 0.01), 1e-6) ** 2 for s in self.sensors])
        A0, _ = self.comp.matrices(0.0, 1.0)
        tau = 1.0 / np.maximum(-np.diag(A0), 1e-12)
        observed = self.C.any(axis=0)
        self.q = np.array([(process_K or {}).get(n, 0.1) ** 2 / tau[i] if observed[i] else 0.0
                           for i, n in enumerate(self.comp.names)])
        self._levels: dict[tuple, tuple] = {}
        self.x: np.ndarray | None = None
        self._last: tuple | None = None  # (time s, speed rpm, ambient °C, coolant °C) of the last row
        self._row_key: tuple | None = None  # (speed, dt) of the stacked one-row matrix below

    def reset(self) -> None:
        """Forget the state: the next row starts the filter again (at rest, observed nodes set to the readings).
        The per-level filter matrices stay cached."""
        self.x = None
        self._last = None
        self._row_key = None

    def _level(self, speed: float, coolant_flow: float, dt: float) -> tuple:
        """(F = (I − KC)Φ, G = (I − KC)Γ, K) of one level, cached."""
        key = (speed, coolant_flow, dt)
        if key not in self._levels:
            Phi, Gam = self.comp.step(speed, coolant_flow, dt, "exact")
            Q = np.diag(self.q * dt) + 1e-12 * np.eye(len(Phi))
            self._levels[key] = steady_filter(Phi, Gam, self.C, Q, self.R)[:3]
        return self._levels[key]

    def start(self, speed: float, ambient: float, coolant: float, temperatures: np.ndarray) -> np.ndarray:
        """State at a first row: at rest in equilibrium with its boundaries, observed nodes set to the readings."""
        u = np.zeros(self.comp.n_inputs)
        u[0], u[1], u[2] = 1.0, ambient, coolant
        x = self.comp.steady_state(0.0, 1.0, u)
        if len(self.sensors):
            x = x + np.linalg.pinv(self.C) @ (temperatures - self.offsets - self.C @ x)
        return x

    def run(self, time_s: np.ndarray, speed: np.ndarray, ambient: np.ndarray, coolant: np.ndarray,
            temperatures: np.ndarray) -> np.ndarray:
        """Filtered node temperatures (°C, rows × nodes) over a block of rows, continuing from the last state
        (or starting at the first row); the state then sits at the last row."""
        t = np.asarray(time_s, dtype=float)
        n = len(t)
        out = np.empty((n, len(self.comp.names)))
        first = 0
        if self.x is None:
            self.x = out[0] = self.start(float(speed[0]), float(ambient[0]), float(coolant[0]), temperatures[0])
            self._last = (float(t[0]), float(speed[0]), float(ambient[0]), float(coolant[0]))
            first = 1
        if first >= n:
            return out
        # row k is reached from the inputs of the row before it (held over the step)
        t_prev = np.r_[self._last[0], t[:-1]][first:]
        sp_prev = np.r_[self._last[1], speed[:-1]][first:]
        amb_prev = np.r_[self._last[2], ambient[:-1]][first:]
        cool_prev = np.r_[self._last[3], coolant[:-1]][first:]
        dt = np.round(t[first:] - t_prev, 9)
        y = temperatures[first:] - self.offsets
        keys = np.column_stack([sp_prev, dt])
        change = np.flatnonzero(np.any(keys[1:] != keys[:-1], axis=1)) + 1
        x = self.x
        for a, b in zip(np.r_[0, change], np.r_[change, len(dt)]):
            F, G, K = self._level(float(sp_prev[a]), 1.0, float(dt[a]))
            W = G[:, 0][None, :] + amb_prev[a:b, None] * G[:, 1][None, :] + cool_prev[a:b, None] * G[:, 2][None, :]
            if K.shape[1]:
                W = W + y[a:b] @ K.T
            out[first + a:first + b] = propagate(F, x, W)
            x = out[first + b - 1]
        self.x = x.copy()
        self._last = (float(t[-1]), float(speed[-1]), float(ambient[-1]), float(coolant[-1]))
        return out

    def update(self, time_s: float, speed: float, ambient: float, coolant: float,
               temperatures: np.ndarray) -> np.ndarray:
        """One row: the filtered node temperatures (°C) at it, as one matrix-vector product
        [F | K | G₀ − K·offsets | G_ambient | G_coolant] · [x; y; 1; ambient; coolant], the matrix stacked once per
        level (at this size numpy's per-call overhead, not arithmetic, is the cost of a row)."""
        if self.x is None:
            self.x = self.start(speed, ambient, coolant, temperatures)
        else:
            t0, sp0, amb0, cool0 = self._last
            key = (sp0, round(time_s - t0, 9))
            if key != self._row_key:
                F, G, K = self._level(sp0, 1.0, key[1])
                constant = G[:, 0] - K @ self.offsets
                self._row_key = key
                self._row_matrix = np.hstack([F, K, constant[:, None], G[:, 1:3]])
                self._row_input = np.ones(self._row_matrix.shape[1])
            v, n, m = self._row_input, len(self.x), len(temperatures)
            v[:n], v[n:n + m], v[-2], v[-1] = self.x, temperatures, amb0, cool0
            self.x = self._row_matrix @ v
        self._last = (time_s, speed, ambient, coolant)
        return self.x
