"""The calibration objective: θ → weighted residuals of the re-simulated recording, with the linear parameters
solved inside each evaluation (variable projection).

For every θ the network is simulated over the recording's inputs by the engine
(:meth:`CompiledNetwork.trajectory`) and the parameters that enter the outputs linearly are solved by linear
least squares: per temperature channel its sensor offset (K) (and, for the ``auto`` network, its heat amplitude),
per displacement channel its sensitivities (µm/K, tilt µm/K, centrifugal µm) and probe offset (µm). The
sensitivities are ridge-regularised on standardised regressors (node temperatures of one machine are strongly
collinear; unpenalised they reach ±1e4 µm/K): the strength is chosen by blocked cross-validation on contiguous
time blocks of the fit grid (:meth:`Problem.choose_ridge`), 0 included, so a well-posed map is not shrunk (the
auto network's map keeps a least strength, ``min_ridge``: see ``fit.AUTO_MIN_RIDGE``). The
residual of each channel is divided by its weight σ: the larger of its noise σ (:func:`noise_sigma`) and its
RMS residual at the start (:meth:`Problem.set_weights`), so °C and µm channels share one scale and, on a real
machine whose model error is far above the sensor noise, sixteen temperature channels cannot drown five
displacement channels (maximum likelihood with an unknown error variance per channel, evaluated at the start;
the temperature channels together then weigh as much as the displacement channels together).

The search compares on a grid read off the recording's own time scales (:func:`fit_rows`), not a fixed number
of samples, so a 1 s recording and a 15 s one of the same programme are fitted on the same grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd
import scipy.linalg

from thermodrift.core import metrics
from thermodrift.core.errors import InputError
from thermodrift.core.physics.calibration.free import FreeParameter, set_values
from thermodrift.core.physics.integrate import CompiledNetwork
from thermodrift.core.physics.network import DisplacementSensor, Network, TemperatureSensor
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.physics.sensors import temperature_reading
from thermodrift.core.recording import TEMPERATURE_ROLES, speed_segments

GRID_PER_BLOCK = 8           # fit-grid steps per shortest speed block
GRID_PER_TAU = 2             # fit-grid steps per shortest warm-up time constant
MAX_FIT_SAMPLES = 20000      # safety cap on the fit grid; beyond it the step grows (and the result says so)
RIDGE_GRID = (0.0, 1e-8, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)  # × samples; penalty on standardised sensitivities
CV_BLOCKS = 5


def noise_sigma(values: np.ndarray) -> float:
    """Noise σ of a channel from its high-frequency residual: MAD of second differences / √6 (robust to the
    signal's own curvature and to speed-step jumps); std when quantization makes the MAD zero; floored at
    1e-6 of the channel's range so a flat channel cannot take an infinite weight."""
    x = np.asarray(values, dtype=float)
    d2 = np.diff(x, 2)
    if len(d2) < 3:
        return max(float(np.ptp(x)) * 1e-3, 1e-9)
    s = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)
    if s == 0.0:
        s = float(np.std(d2)) / math.sqrt(6.0)
    return max(s, 1e-6 * float(np.ptp(x)), 1e-9)


def fit_rows(time_s: np.ndarray, speed_rpm: np.ndarray | None, time_constants_s: Sequence[float] = (),
             max_samples: int = MAX_FIT_SAMPLES) -> tuple[np.ndarray, float]:
    """Rows of the fit grid and its step (s): the shorter of the recording's shortest speed block over
    :data:`GRID_PER_BLOCK` and its shortest warm-up time constant over :data:`GRID_PER_TAU` (the simulation
    between grid points stays exact: inputs are held), a whole number of samples, plus the first sample of every
    speed block (so held inputs change exactly where the speed does).
    The step grows if the grid would exceed ``max_samples``."""
    t = np.asarray(time_s, dtype=float)
    if len(t) < 3:
        return np.arange(len(t)), 0.0
    dt = float(np.median(np.diff(t)))
    duration = float(t[-1] - t[0])
    segments = speed_segments(t, speed_rpm) if speed_rpm is not None else []
    scales = ([(float(t[b - 1] - t[a]) + dt) / GRID_PER_BLOCK for a, b, _ in segments]
              + [s / GRID_PER_TAU for s in time_constants_s if s > 0])
    step = max(dt, min(scales) if scales else duration, duration / max(max_samples - len(segments) - 2, 1))
    step = dt * round(step / dt)  # whole samples: equal steps share one cached step matrix
    marks = np.arange(t[0], t[-1], step)
    rows = np.searchsorted(t, marks - 1e-9 * max(step, 1.0))
    rows = np.unique(np.r_[rows, [a for a, _, _ in segments], len(t) - 1]).astype(int)
    return rows, step


@dataclass
class Channel:
    name: str
    kind: str            # "temperature" | "displacement"
    unit: str
    sigma: float         # noise σ (K, µm)
    measured: np.ndarray
    weight: float = 0.0  # σ the residual is divided by (≥ sigma); set by Problem.set_weights


@dataclass
class Sim:
    """One simulation: the network, node temperatures X (°C) and their response to the boundaries alone."""

    net: Network
    X: np.ndarray
    X_boundary: np.ndarray


class _Arrays:
    """The numeric signals of a :class:`Scenario` read once (what :meth:`CompiledNetwork.trajectory` reads):
    column access on the scenario's frame, which also holds condition labels, costs more than a small
    simulation."""

    def __init__(self, scenario: Scenario):
        self.frame = scenario.frame.drop(columns="condition")
        self.time_s = scenario.time_s


class Problem:
    """Maps θ (search coordinates of the free parameters) → weighted, projected residuals for one recording.

    Heat amplitudes with ``projected_by`` set are linear too: their node is read by one sensor and exchanges heat
    only with the ambient, so the reading is boundary response + Q·(response to 1 W). The search simulates them
    at 1 W and solves Q ≥ 0 with the channel's offset; the displacements then see the scaled node temperatures.
    """

    def __init__(self, network: Network, free: list[FreeParameter], recording, targets: Sequence[str] | None,
                 time_constants_s: Sequence[float] = (), max_fit_samples: int = MAX_FIT_SAMPLES,
                 ambient_degC: float = 20.0, min_ridge: float = 0.0):
        self.network = network
        self.time_constants_s, self.max_fit_samples = list(time_constants_s), max_fit_samples
        self.ambient_degC, self.min_ridge = ambient_degC, min_ridge
        projected = [p.name for p in free if p.scale == "projected"]
        if projected:
            raise InputError(f"free parameter(s) {projected} have scale 'projected': the linear step solves them",
                             hint="search only log and linear parameters")
        self.free = [p for p in free if p.projected_by is None]
        self.projected = {p.projected_by: p for p in free if p.projected_by is not None}
        self.scenario = Scenario.from_recording(recording, ambient_degC=ambient_degC)
        self.time_s = recording.time_s
        self.speed_ratio = self.scenario.frame["speed_rpm"].to_numpy() / network.reference_speed_rpm
        data = recording.data
        disp_cols = set(recording.columns("displacement"))
        if targets:
            unknown = [c for c in targets if c not in disp_cols]
            if unknown:
                raise InputError(f"targets {unknown} are not displacement channels of {recording.source}",
                                 hint=f"choose from {sorted(disp_cols)}")
        temp_cols = {c for r in TEMPERATURE_ROLES for c in recording.columns(r)}
        self.temp_sensors = [s for s in network.temperature_sensors if s.name in temp_cols]
        self.disp_sensors = [s for s in network.displacement_sensors if s.name in disp_cols
                             and (not targets or s.name in targets)]
        if not self.temp_sensors and not self.disp_sensors:
            raise InputError(f"no sensor of network {network.name!r} matches a channel of {recording.source}",
                             hint="sensor names in the spec must equal the recording's column names")
        self.channels = [Channel(s.name, "temperature", "K", noise_sigma(data[s.name]), data[s.name].to_numpy(float))
                         for s in self.temp_sensors]
        self.channels += [Channel(s.name, "displacement", "um", noise_sigma(data[s.name]),
                                  data[s.name].to_numpy(float)) for s in self.disp_sensors]
        self.measured = {c.name: c.measured for c in self.channels}
        speed = self.scenario.frame["speed_rpm"].to_numpy()
        self.rows, self.grid_step_s = fit_rows(self.time_s, speed if np.ptp(speed) > 0 else None, time_constants_s,
                                               max_fit_samples)
        # The search simulates on the fit grid (inputs held from each grid sample; exact for the held inputs),
        # final predictions use the full grid.
        fit_scenario = Scenario(self.scenario.frame.iloc[self.rows], self.scenario.name)
        self.arrays = {False: _Arrays(fit_scenario), True: _Arrays(self.scenario)}
        self.resting = {full: _Arrays(Scenario(scen.frame.assign(
            speed_rpm=0.0, cutting_power_W=0.0, axis_velocity_mm_min=0.0), scen.name))
            for full, scen in ((False, fit_scenario), (True, self.scenario))}
        self.boundaries = {"ambient": self.scenario.frame["ambient_degC"].to_numpy(),
                           "coolant": self.scenario.frame["coolant_inlet_degC"].to_numpy()}
        self.constant_boundaries = all(np.ptp(v) == 0 for v in self.boundaries.values())
        self.groups: dict[tuple[str, ...], list[DisplacementSensor]] = {}
        for s in self.disp_sensors:  # channels sharing regressors are solved in one lstsq
            self.groups.setdefault(tuple(self.regressor_names(s)), []).append(s)
        self.ridge = {names: 0.0 for names in self.groups}  # λ / samples per regressor group
        self.n_linear = (len(self.temp_sensors) + len(self.projected)
                         + sum(len(self.regressor_names(s)) + 1 for s in self.disp_sensors))
        self.balance = True
        self.best: tuple[float, np.ndarray] | None = None
        self.evaluations = 0

    # θ <-> network
    @property
    def theta0(self) -> np.ndarray:
        return np.array([p.to_search(p.value) for p in self.free])

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([p.to_search(p.low) for p in self.free]),
                np.array([p.to_search(p.high) for p in self.free]))

    def network_at(self, theta: np.ndarray, heat: Mapping[str, float] | None = None) -> Network:
        """The network at θ with projected heat amplitudes at ``heat`` (default 1 W each, the unit response)."""
        values = {path: x for p, v in zip(self.free, theta) for path, x in p.path_values(p.from_search(v)).items()}
        values.update({path: (heat or {}).get(p.name, 1.0) for p in self.projected.values() for path in p.paths})
        return set_values(self.network, values)

    def regressor_names(self, sensor: DisplacementSensor) -> list[str]:
        out = self.network.output(sensor.output)
        names = list(out.sensitivity_um_K) or self.network.node_names
        names += [f"tilt:{h}/{c}" for h, c, _ in out.tilt_pairs()]
        return names + (["centrifugal"] if out.centrifugal_um else [])

    # simulation and projection
    def simulate(self, theta: np.ndarray, full: bool = False) -> Sim:
        """The network at θ and its node temperatures on the fit grid (or the full grid)."""
        net = self.network_at(theta)
        comp = CompiledNetwork(net)
        X = comp.trajectory(self.arrays[full])
        if not self.projected:
            Xb = X
        elif self.constant_boundaries:  # at rest in equilibrium with constant boundaries
            Xb = np.broadcast_to(X[0], X.shape)
        else:
            Xb = comp.trajectory(self.resting[full])
        return Sim(net, X, Xb)

    def _design(self, names: tuple[str, ...], X: np.ndarray, idx: Mapping[str, int], ratio: np.ndarray) -> np.ndarray:
        cols = []
        for name in names:
            if name == "centrifugal":
                cols.append(ratio ** 2)
            elif name.startswith("tilt:"):
                h, c = name[5:].split("/", 1)
                cols.append((X[:, idx[h]] - X[0, idx[h]]) - (X[:, idx[c]] - X[0, idx[c]]))
            else:
                cols.append(X[:, idx[name]] - X[0, idx[name]])
        return np.column_stack(cols + [np.ones(len(X))])

    def outputs(self, sim: Sim, linear: Mapping[str, Mapping[str, float]] | None = None,
                full: bool = False) -> dict[str, Any]:
        """Predicted channels on the fit grid with the linear parameters solved there (``linear`` None), or on
        the grid of the simulation with the given linear parameters. Also returns the design matrices of the
        displacement groups (``designs``: names -> A)."""
        net, X = sim.net, sim.X.copy()
        idx = {n: i for i, n in enumerate(net.node_names)}
        grid = slice(None) if full else self.rows
        time_s, ratio = self.time_s[grid], self.speed_ratio[grid]
        solve = linear is None
        preds: dict[str, np.ndarray] = {}
        linear = {} if solve else {k: dict(v) for k, v in linear.items()}

        def reading(s: TemperatureSensor, nodes: np.ndarray) -> np.ndarray:
            values = {n: nodes[:, idx[n]] if n in idx else self.boundaries[n][grid] for n in s.weights}
            return temperature_reading(s, values, time_s, offset=False)

        for s in self.temp_sensors:
            base = reading(s, X)
            proj = self.projected.get(s.name)
            if proj is not None:
                node = idx[next(iter(s.weights))]
                base_b = reading(s, sim.X_boundary)
                phi = base - base_b
                if solve:
                    target = self.measured[s.name][grid] - base_b
                    dphi = phi - phi.mean()
                    den = float(dphi @ dphi)
                    q = float(dphi @ (target - target.mean())) / den if den > 0 else 0.0
                    off = float(target.mean() - q * phi.mean())
                    if q < 0:  # heat cannot be negative: the channel does not warm with speed
                        q, off = 0.0, float(np.mean(target))
                    linear[s.name] = {"offset_K": float(off), proj.name: float(q)}
                q = linear[s.name][proj.name]
                X[:, node] = sim.X_boundary[:, node] + q * (sim.X[:, node] - sim.X_boundary[:, node])
                base = base_b + q * phi
            elif solve:
                linear[s.name] = {"offset_K": float(np.mean(self.measured[s.name][grid] - base))}
            preds[s.name] = base + linear[s.name]["offset_K"]
        designs = {}
        for names, sensors in self.groups.items():
            A = designs[names] = self._design(names, X, idx, ratio)
            if solve:
                Y = np.column_stack([self.measured[s.name][grid] for s in sensors])
                beta = ridge_solve(A, Y, self.ridge[names])
                for j, s in enumerate(sensors):
                    linear[s.name] = {**{n: float(v) for n, v in zip(names, beta[:-1, j])},
                                      "offset_um": float(beta[-1, j])}
            for s in sensors:
                preds[s.name] = A @ np.array([linear[s.name][n] for n in names] + [linear[s.name]["offset_um"]])
        return {"predictions": preds, "linear": linear, "designs": designs}

    def choose_ridge(self, theta: np.ndarray) -> dict[tuple[str, ...], float]:
        """Set each displacement group's ridge strength by blocked cross-validation at θ (see module docstring):
        the grid value whose fits on all but one of :data:`CV_BLOCKS` contiguous blocks predict the held-out
        block best (summed over the group's channels), not below ``min_ridge``; ties go to the weaker penalty."""
        designs = self.outputs(self.simulate(theta))["designs"]
        for names, sensors in self.groups.items():
            Y = np.column_stack([self.measured[s.name][self.rows] for s in sensors])
            self.ridge[names] = cv_ridge(designs[names], Y, self.min_ridge)
        return dict(self.ridge)

    def set_weights(self, theta: np.ndarray) -> None:
        """Each channel's weight σ: max(noise σ, RMS residual on the fit grid at θ) (see module docstring); with
        both kinds present, temperature weights are widened by √(n_temperature / n_displacement) so the two
        kinds weigh alike at the start however many sensors each has."""
        preds = self.outputs(self.simulate(theta))["predictions"]
        n_t = sum(c.kind == "temperature" for c in self.channels)
        n_d = len(self.channels) - n_t
        for c in self.channels:
            rms = float(metrics.rmse(c.measured[self.rows], preds[c.name]))
            c.weight = max(c.sigma, rms)
            if self.balance and c.kind == "temperature" and n_d and n_t > n_d:
                c.weight *= math.sqrt(n_t / n_d)

    def heat(self, linear: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        """Projected heat amplitudes (W) from solved linear parameters."""
        return {p.name: linear[ch][p.name] for ch, p in self.projected.items() if ch in linear}

    def weighted(self, preds: Mapping[str, np.ndarray]) -> np.ndarray:
        """Residuals on the fit grid divided by each channel's noise σ, channels one after another."""
        return np.concatenate([(c.measured[self.rows] - preds[c.name]) / (c.weight or c.sigma)
                                for c in self.channels])

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        r = self.weighted(self.outputs(self.simulate(theta))["predictions"])
        self.evaluations += 1
        cost = float(r @ r)
        if not np.isfinite(cost):
            return np.full_like(r, 1e6)
        if self.best is None or cost < self.best[0]:
            self.best = (cost, np.array(theta, dtype=float))
        return r


def _scaled(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Regressor columns scaled to unit RMS (the last, constant column kept): (A', scale)."""
    scale = np.ones(A.shape[1])
    if A.shape[1] > 1:
        scale[:-1] = np.maximum(metrics.rms(A[:, :-1], axis=0), 1e-12)
    return A / scale, scale


def cv_ridge(A: np.ndarray, Y: np.ndarray, min_ridge: float = 0.0) -> float:
    """The ridge strength of :data:`RIDGE_GRID` (not below ``min_ridge``) whose fits of Y ≈ A β on all but one
    of :data:`CV_BLOCKS` contiguous blocks predict the held-out block best (summed over Y's columns); ties go to
    the weaker penalty."""
    As, _ = _scaled(A)
    folds = np.array_split(np.arange(len(As)), CV_BLOCKS)
    G, b = As.T @ As, As.T @ Y
    P = np.eye(As.shape[1])
    P[-1, -1] = 0.0
    grid = [lam for lam in RIDGE_GRID if lam >= min_ridge]
    errors = []
    for lam in grid:
        sse = 0.0
        for test in folds:
            At = As[test]
            beta = _solve(G - At.T @ At + lam * (len(As) - len(test)) * P, b - At.T @ Y[test])
            sse += float(((Y[test] - At @ beta) ** 2).sum())
        errors.append(sse)
    return grid[int(np.argmin(errors))]


def _solve(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solution of the small symmetric system M x = b; least squares when M is singular."""
    try:
        return np.linalg.solve(M, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(M, b, rcond=1e-12)[0]


def ridge_solve(A: np.ndarray, Y: np.ndarray, lam: float) -> np.ndarray:
    """Coefficients of Y ≈ A β with ridge penalty λ·n·‖β'‖² on the standardised regressors (not the last,
    constant column). Normal equations of the scaled columns (p ≤ ~20, so a p × p solve); unpenalised, they
    fall back to QR least squares, which stays accurate for collinear columns."""
    As, scale = _scaled(A)
    if lam > 0:
        P = np.eye(A.shape[1])
        P[-1, -1] = 0.0
        beta = _solve(As.T @ As + lam * len(A) * P, As.T @ Y)
    else:
        beta = scipy.linalg.lstsq(As, Y, lapack_driver="gelsy", check_finite=False, cond=1e-10)[0]
    return beta / scale[:, None]


def ridge_covariance(A: np.ndarray, lam: float) -> np.ndarray:
    """Covariance of :func:`ridge_solve`'s β per unit residual variance: M⁻¹ AᵀA M⁻¹ with M = AᵀA + λ·n·P."""
    As, scale = _scaled(A)
    G = As.T @ As
    P = np.eye(A.shape[1])
    P[-1, -1] = 0.0
    M = np.linalg.pinv(G + lam * len(A) * P)
    return (M @ G @ M) / np.outer(scale, scale)


def frame_of(problem: Problem, preds: Mapping[str, np.ndarray]) -> pd.DataFrame:
    """Predictions on the full grid as a frame indexed by time (s), columns in channel order."""
    index = pd.Index(problem.time_s, name="time_s")
    return pd.DataFrame({c.name: preds[c.name] for c in problem.channels}, index=index)
