"""Models ``lptn`` and ``lptn_hybrid``: the calibrated lumped-parameter thermal network as a thermal-error model.

``lptn`` fits by calibrating the ``auto`` baseline network
(:func:`thermodrift.core.physics.calibration.auto_network`: speed-driven heat, one node per temperature sensor plus
hidden nodes, constant convection, linear expansion map) on the training part. It predicts as a controller runs it:
a state observer (a steady-state Kalman filter over the calibrated network,
:class:`thermodrift.core.physics.calibration.StateObserver`) carries the node temperatures from row to row,
corrected by the measured temperatures; the hidden nodes run on the speed (and ambient) history. Displacement is the
expansion map of the observed state, refitted on the training states with its ridge strength chosen there by blocked
cross-validation (:func:`thermodrift.core.physics.calibration.cv_ridge`). ``history_length = None``:
``predict(X, history)`` starts the observer at the first history row (else at the first row of ``X``, at rest
with its readings), and ``streamer(history)`` carries the observer state so each ``update(row)`` is one filter step.

``lptn_hybrid`` adds a data-driven residual model: ridge regression (``alpha``) of the training residual
y − physics on the standardised measured temperatures and the physics prediction.

Both set ``extra_input_roles = ("temperature", "speed", "ambient")``: the study appends every temperature
channel the selector left out (a network wants them all), the speed column and ambient columns, and passes each
column's role in ``X.attrs["roles"]`` (``{column: role}``). The speed column (rpm) is the one with role
``speed``, the ambient column (°C) the first with role ``ambient``, and every other column a temperature (°C);
the ``speed_column`` / ``ambient_column`` parameters name them instead, for frames without roles.
"""

from __future__ import annotations

import copy
import hashlib
from typing import Any, ClassVar

import numpy as np
import pandas as pd
from sklearn.linear_model import Ridge

from thermodrift.core.components import Streamer, ThermalModel, run_slices, same_run
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics import calibration as cal
from thermodrift.core.recording import Channel, Recording


def input_roles(X: pd.DataFrame, speed_column: str | None = None,
                ambient_column: str | None = None) -> tuple[str, str | None, list[str]]:
    """(speed column, ambient column or None, temperature columns) of a model input frame, from the roles the
    study passes in ``X.attrs["roles"]``; ``speed_column`` / ``ambient_column`` name them instead."""
    roles = dict(X.attrs.get("roles", {}))
    cols = [str(c) for c in X.columns]
    speed = speed_column or next((c for c in cols if roles.get(c) == "speed"), None)
    ambient = ambient_column or next((c for c in cols if roles.get(c) == "ambient"), None)
    for name, column in (("speed_column", speed_column), ("ambient_column", ambient_column)):
        if column is not None and column not in cols:
            raise ValueError(f"lptn: {name}={column!r} is not among the input columns {cols}")
    if speed is None:
        raise ValueError(f"lptn needs the spindle speed among its inputs: none of {cols} has role 'speed' in "
                         "X.attrs['roles'] (the study passes the roles of extra_input_roles); pass speed_column=")
    temps = [c for c in cols if c not in (speed, ambient)]
    return speed, ambient, temps


_CALIBRATIONS: dict[str, Any] = {}  # recent calibrations by their inputs (see _calibrated)
_CALIBRATIONS_KEPT = 4


def _calibrated(recording: Recording, **kwargs) -> cal.CalibrationResult:
    """``cal.calibrate(recording, **kwargs)``, computed once per process for the same data and settings: the
    calibration is deterministic and takes minutes, and ``lptn`` and ``lptn_hybrid`` fitted on the same rows (as
    AutoML does on every inner fold) share it. A copy is returned, so no model holds another's objects."""
    data = recording.data
    digest = hashlib.sha1(np.ascontiguousarray(data.to_numpy(dtype=float)).tobytes())
    digest.update(np.asarray(data.index, dtype=float).tobytes())
    roles = [(str(c), ch.role) for c, ch in recording.channels.items()]
    digest.update(repr((list(map(str, data.columns)), roles, sorted(kwargs.items()))).encode())
    key = digest.hexdigest()
    if key not in _CALIBRATIONS:
        while len(_CALIBRATIONS) >= _CALIBRATIONS_KEPT:
            _CALIBRATIONS.pop(next(iter(_CALIBRATIONS)))
        _CALIBRATIONS[key] = cal.calibrate(recording, **kwargs)
    return copy.deepcopy(_CALIBRATIONS[key])


class LPTN(ThermalModel):
    """Calibrated auto baseline network with a state observer (see the module docstring).

    ``hidden_nodes``: unobserved nodes acting on the displacements; ``max_evaluations``: iteration cap of the
    calibration search; ``max_fit_samples``: cap of its fit grid (samples); ``jitter_seed``: None starts the
    calibration at the auto network's start, an int at that start jittered from this seed (to measure how much
    the model depends on its start).
    """

    automl_cost = "medium"  # a calibration per fit: between the linear families and the networks

    extra_input_roles: ClassVar[tuple[str, ...]] = ("temperature", "speed", "ambient")
    # The auto network's heat inputs are driven by the spindle speed; without it nothing heats the hidden nodes.
    requires_roles: ClassVar[tuple[str, ...]] = ("speed",)
    history_length: ClassVar[int | None] = None

    def __init__(self, hidden_nodes: int = 2, max_evaluations: int = 100, max_fit_samples: int = 20000,
                 speed_column: str | None = None, ambient_column: str | None = None, jitter_seed: int | None = None,
                 grouped: bool = False):
        self.hidden_nodes = hidden_nodes
        self.max_evaluations = max_evaluations
        self.max_fit_samples = max_fit_samples
        self.speed_column = speed_column
        self.ambient_column = ambient_column
        self.jitter_seed = jitter_seed
        self.grouped = grouped

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"hidden_nodes": 1, "max_evaluations": 5, "max_fit_samples": 150},
                {"hidden_nodes": 0, "max_evaluations": 5, "max_fit_samples": 150}]

    @classmethod
    def search_space(cls) -> dict[str, dict[str, Any]]:
        return {"hidden_nodes": {"type": "int", "low": 0, "high": 4}}

    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        self.speed_, self.ambient_, self.temperatures_ = input_roles(X, self.speed_column, self.ambient_column)
        targets = [f"y:{t}" for t in self.target_names_]
        data = X[[*self.temperatures_, self.speed_, *([self.ambient_] if self.ambient_ else [])]].copy()
        data.index = pd.Index(np.asarray(X.index, dtype=float), name="time_s")
        channels = {c: Channel(c, "temperature", "degC", {}) for c in self.temperatures_}
        channels[self.speed_] = Channel(self.speed_, "speed", "rpm", {})
        if self.ambient_:
            channels[self.ambient_] = Channel(self.ambient_, "ambient", "degC", {})
        for name, column in zip(targets, y.T):
            data[name] = column
            channels[name] = Channel(name, "displacement", "um", {})
        recording = Recording(data, channels, source="lptn training data")
        result = _calibrated(recording, hidden_nodes=self.hidden_nodes, max_evaluations=self.max_evaluations,
                             max_fit_samples=self.max_fit_samples, intervals=False, jitter_seed=self.jitter_seed,
                             grouped=self.grouped)
        self.network_ = result.network
        nodes = {s.name: s.weights for s in self.network_.temperature_sensors}
        self.observer_ = cal.StateObserver(
            self.network_, self.temperatures_, noise_K=result.sigma,
            process_K={next(iter(nodes[c])): max(result.rmse[c], result.sigma[c]) for c in self.temperatures_})
        t, speed, ambient, temps = self._columns(X)
        u = np.zeros(self.observer_.comp.n_inputs)
        u[:3] = 1.0, ambient[0], ambient[0]
        self.reference_ = self.observer_.comp.steady_state(0.0, 1.0, u)
        states = self._observe(self._fresh(), X)
        # the expansion map refitted on the observed states, its ridge strength chosen there by blocked CV
        A = np.column_stack([states - self.reference_, np.ones(len(states))])
        self.ridge_ = cal.cv_ridge(A, y)
        beta = cal.ridge_solve(A, y, self.ridge_)
        self.coef_, self.intercept_ = beta[:-1], beta[-1]
        self.rmse_calibration_ = result.rmse

    def _columns(self, X: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(time s, speed rpm, ambient °C, temperatures °C) of ``X``."""
        t = np.asarray(X.index, dtype=float)
        speed = np.round(np.clip(X[self.speed_].to_numpy(dtype=float), 0.0, None) / 10.0) * 10.0
        ambient = (X[self.ambient_].to_numpy(dtype=float) if self.ambient_
                   else np.full(len(X), cal.AUTO_AMBIENT_DEGC))
        return t, speed, ambient, X[self.temperatures_].to_numpy(dtype=float)

    def _fresh(self) -> cal.StateObserver:
        obs = copy.copy(self.observer_)
        obs.reset()
        return obs

    def _observe(self, obs: cal.StateObserver, X: pd.DataFrame) -> np.ndarray:
        """Observed states over ``X``; each later run of ``X`` starts a fresh observer at its first row."""
        parts = run_slices(X)
        if len(parts) > 1:
            return np.concatenate([self._observe(obs if k == 0 else self._fresh(), X.iloc[s])
                                   for k, s in enumerate(parts)])
        t, speed, ambient, temps = self._columns(X)
        return obs.run(t, speed, ambient, ambient, temps)

    def physics(self, X: pd.DataFrame) -> np.ndarray:
        """Displacements (µm, n × k) of the observed network state over ``X`` (observer started at its first row)."""
        return (self._observe(self._fresh(), X) - self.reference_) @ self.coef_ + self.intercept_

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        return self.physics(X)

    def streamer(self, history: pd.DataFrame | None = None) -> "_LPTNStreamer":
        return _LPTNStreamer(self, history)

    def _row_map(self) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray]:
        """(W_x, W_T, w_ambient, c): one streamed row's output is x·W_x + T·W_T + ambient·w_ambient + c for its
        observed state x and readings T (the hybrid folds its residual model in; None: no such term)."""
        return self.coef_, None, None, self.intercept_ - self.reference_ @ self.coef_

    def export_state(self) -> dict:
        """Runtime ``lptn``: the network's (A, B) per 10 rpm speed level from 0 to twice the training maximum, the
        observer's matrices and the read-out of :meth:`_row_map` (the auto network's reference speed is the
        training maximum)."""
        comp = self.observer_.comp
        top = 2.0 * self.network_.reference_speed_rpm
        levels = [comp.matrices(s, 1.0) for s in np.arange(0.0, top + 10.0, 10.0)]
        W_x, W_T, w_ambient, c = self._row_map()
        return {"runtime": "lptn", "inputs": [str(col) for col in self.feature_names_in_],
                "targets": list(self.target_names_), "history_length": None,
                "temperature_columns": list(self.temperatures_), "speed_column": self.speed_,
                "ambient_column": self.ambient_, "ambient_default_degC": cal.AUTO_AMBIENT_DEGC,
                "speed_step_rpm": 10.0, "A": np.array([a for a, _ in levels]),
                "B": np.array([b[:, :3] for _, b in levels]), "C": self.observer_.C,
                "offsets": self.observer_.offsets, "R": self.observer_.R, "q": self.observer_.q,
                "W_x": W_x, "W_T": W_T, "w_ambient": w_ambient, "c": c}


class _LPTNStreamer(Streamer):
    """One observer step per row (the row's name is its time in s)."""

    def __init__(self, model: LPTN, history: pd.DataFrame | None = None):
        self.model = model
        self.obs = model._fresh()
        self.columns = [*model.temperatures_, model.speed_, *([model.ambient_] if model.ambient_ else [])]
        self.W_x, self.W_T, self.w_ambient, self.c = model._row_map()
        history = same_run(history)
        if history is not None and len(history):
            model._observe(self.obs, history)

    def update(self, row) -> np.ndarray:
        m = self.model
        v = self.values(row)
        n = len(m.temperatures_)
        temps = v[:n]
        speed = round(max(float(v[n]), 0.0) / 10.0) * 10.0
        ambient = float(v[n + 1]) if m.ambient_ else cal.AUTO_AMBIENT_DEGC
        time_s = getattr(row, "name", None)
        if not isinstance(time_s, (int, float, np.number)):
            raise ValueError("a physics model steps its state by time: pass each row as a pandas Series named by "
                             "its time in s (e.g. frame.loc[t])")
        x = self.obs.update(float(time_s), speed, ambient, ambient, temps)
        out = x @ self.W_x + self.c
        if self.W_T is not None:
            out += temps @ self.W_T
        if self.w_ambient is not None:
            out += ambient * self.w_ambient
        return out


class LPTNHybrid(LPTN):
    """Physics plus a ridge model (``alpha``) of its training residual on temperatures and physics output."""

    def __init__(self, hidden_nodes: int = 2, max_evaluations: int = 100, max_fit_samples: int = 20000,
                 alpha: float = 10.0, speed_column: str | None = None, ambient_column: str | None = None,
                 jitter_seed: int | None = None, grouped: bool = False):
        super().__init__(hidden_nodes, max_evaluations, max_fit_samples, speed_column, ambient_column, jitter_seed,
                         grouped)
        self.alpha = alpha

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"hidden_nodes": 1, "max_evaluations": 5, "max_fit_samples": 150, "alpha": 1.0},
                {"hidden_nodes": 0, "max_evaluations": 5, "max_fit_samples": 150, "alpha": 100.0}]

    @classmethod
    def search_space(cls) -> dict[str, dict[str, Any]]:
        return {**super().search_space(), "alpha": {"type": "float", "low": 1e-3, "high": 1e3, "log": True}}

    def _features(self, X: pd.DataFrame, phys: np.ndarray) -> np.ndarray:
        cols = [*self.temperatures_, *([self.ambient_] if self.ambient_ else [])]
        return np.column_stack([X[cols].to_numpy(dtype=float), phys])

    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        super()._fit(X, y)
        phys = self.physics(X)
        F = self._features(X, phys)
        self.f_mean_, self.f_scale_ = F.mean(axis=0), F.std(axis=0) + 1e-12
        ridge = Ridge(alpha=self.alpha, solver="svd").fit((F - self.f_mean_) / self.f_scale_, y - phys)
        # kept as arrays: one streamed row is then one dot product
        self.res_coef_ = np.asarray(ridge.coef_, dtype=float).reshape(y.shape[1], -1).T / self.f_scale_[:, None]
        self.res_intercept_ = np.asarray(ridge.intercept_, dtype=float).reshape(-1) - self.f_mean_ @ self.res_coef_

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        phys = self.physics(X)
        return phys + self._features(X, phys) @ self.res_coef_ + self.res_intercept_

    def _row_map(self) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray]:
        # physics p = x·coef + b; output = p + T·R_T + p·R_p + ambient·R_a + r = x·coef(I + R_p) + …
        coef, _, _, b = super()._row_map()
        k = coef.shape[1]
        n = len(self.temperatures_)
        R_p = np.eye(k) + self.res_coef_[-k:]
        return (coef @ R_p, self.res_coef_[:n], self.res_coef_[n] if self.ambient_ else None,
                b @ R_p + self.res_intercept_)


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "lptn", LPTN)
    registry.add("model", "lptn_hybrid", LPTNHybrid)
