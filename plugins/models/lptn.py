"""Models ``lptn`` and ``lptn_hybrid``: the calibrated lumped-parameter thermal network as a thermal-error model.

``lptn`` fits by calibrating the ``auto`` baseline network (:func:`thermodrift.core.physics.calibrate.auto_network`:
speed-driven heat, one node per temperature sensor plus hidden nodes, constant convection, linear expansion map)
on the training part, and predicts by simulating the network over the inputs' speed (and ambient) history and
mapping node temperatures to displacement (µm). It reads the measured temperatures only while fitting; the
prediction needs only the speed schedule, so it extrapolates along the physics rather than the regression.
A prediction that starts after the training data continues the simulation from the training end state (inputs
held over any gap); one that starts inside it re-simulates from the training start; otherwise from rest.

``lptn_hybrid`` adds a data-driven residual model: ridge regression (``alpha``) of the training residual
y − physics on the standardised measured temperatures and the physics prediction, so effects the baseline
network leaves out (ambient swings, unmodelled heat paths) are corrected from the sensors.

Both set ``extra_input_roles = ("speed", "ambient")``: the study appends the speed column (and ambient columns
when the recording has them) to the selected temperatures. The columns are recognised by ``X.attrs["roles"]``
(``{column: role}``) when present, else by the ``speed_column`` / ``ambient_column`` parameters, else by name
(``rpm``/``speed``/``spindle``; ``ambient``/``amb``), a speed column also having to look like a schedule
(non-negative, ≥ 100 rpm, at most 64 levels).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pandas as pd
from sklearn.linear_model import Ridge

from thermodrift.core.components import ThermalModel
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics import calibrate as cal
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.recording import Channel, Recording

_SPEED_WORDS = ("rpm", "speed", "spindle")
_AMBIENT_WORDS = ("ambient", "amb_", "amb(", "room")


def _looks_like_speed(values: pd.Series) -> bool:
    """A spindle schedule: non-negative, reaching ≥ 100 rpm, with at most 64 distinct levels."""
    v = values.to_numpy(dtype=float)
    return bool(len(v)) and v.min() >= 0 and v.max() >= 100 and len(np.unique(v)) <= 64


def input_roles(X: pd.DataFrame, speed_column: str | None = None,
                ambient_column: str | None = None) -> tuple[str, str | None, list[str]]:
    """(speed column, ambient column or None, temperature columns) of a model input frame."""
    roles = dict(X.attrs.get("roles", {}))
    cols = [str(c) for c in X.columns]
    speed = speed_column or next((c for c in cols if roles.get(c) == "speed"), None)
    ambient = ambient_column or next((c for c in cols if roles.get(c) == "ambient"), None)
    if speed is None:
        # by name in the order rpm, speed, spindle ("T_spindle" is a temperature), then by value alone
        named = [c for w in _SPEED_WORDS for c in cols if w in c.lower()]
        speed = next((c for c in dict.fromkeys(named + cols) if _looks_like_speed(X[c])), None)
    if speed is None or speed not in cols:
        raise ValueError("lptn needs the spindle speed among its inputs (extra_input_roles); none of "
                         f"{cols} looks like a speed column — pass speed_column=")
    if ambient is None and not roles:
        ambient = next((c for c in cols if c != speed and any(w in c.lower() for w in _AMBIENT_WORDS)), None)
    temps = [c for c in cols if c not in (speed, ambient)]
    return speed, ambient, temps


class LPTN(ThermalModel):
    """Calibrated auto baseline network (see the module docstring).

    ``hidden_nodes``: unobserved nodes acting on the displacements; ``max_seconds``: wall-clock limit of one
    calibration (s); ``max_fit_samples``: grid of the calibration search (samples).
    """

    extra_input_roles: ClassVar[tuple[str, ...]] = ("speed", "ambient")

    def __init__(self, hidden_nodes: int = 2, max_seconds: float = 60.0, max_fit_samples: int = 2500,
                 speed_column: str | None = None, ambient_column: str | None = None):
        self.hidden_nodes = hidden_nodes
        self.max_seconds = max_seconds
        self.max_fit_samples = max_fit_samples
        self.speed_column = speed_column
        self.ambient_column = ambient_column

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"hidden_nodes": 1, "max_seconds": 1.0, "max_fit_samples": 150},
                {"hidden_nodes": 0, "max_seconds": 1.0, "max_fit_samples": 150}]

    @classmethod
    def search_space(cls) -> dict[str, dict[str, Any]]:
        return {"hidden_nodes": {"type": "int", "low": 0, "high": 4}}

    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        self.speed_, self.ambient_, self.temperatures_ = input_roles(X, self.speed_column, self.ambient_column)
        targets = [f"y:{t}" for t in self.target_names_]
        data = X[[*self.temperatures_, self.speed_, *([self.ambient_] if self.ambient_ else [])]].copy()
        channels = {c: Channel(c, "temperature", "degC", {}) for c in self.temperatures_}
        channels[self.speed_] = Channel(self.speed_, "speed", "rpm", {})
        if self.ambient_:
            channels[self.ambient_] = Channel(self.ambient_, "ambient", "degC", {})
        for name, column in zip(targets, y.T):
            data[name] = column
            channels[name] = Channel(name, "displacement", "um", {})
        recording = Recording(data, channels, source="lptn training data")
        self.calibration_ = cal.calibrate(recording, hidden_nodes=self.hidden_nodes, max_seconds=self.max_seconds,
                                          max_fit_samples=self.max_fit_samples, intervals=False)
        self.network_ = self.calibration_.network
        self.outputs_ = targets
        self.train_inputs_ = self._inputs(X)
        _, nodes = cal.predict(self.network_, Scenario(self.train_inputs_, "train"))
        self.reference_state_, self.end_state_ = nodes[0], nodes[-1]

    def _inputs(self, X: pd.DataFrame) -> pd.DataFrame:
        """Speed (rpm) and ambient (°C) of ``X`` indexed by time in s."""
        frame = pd.DataFrame({"speed_rpm": np.clip(X[self.speed_].to_numpy(dtype=float), 0.0, None)},
                             index=pd.Index(np.asarray(X.index, dtype=float), name="time_s"))
        frame["ambient_degC"] = (X[self.ambient_].to_numpy(dtype=float) if self.ambient_
                                 else cal.AUTO_AMBIENT_DEGC)
        return frame

    def physics(self, X: pd.DataFrame) -> np.ndarray:
        """Simulated displacements (µm, n × k) over the inputs' time, continuing the training history."""
        new, train = self._inputs(X), self.train_inputs_
        t0 = new.index[0]
        if t0 > train.index[-1]:
            initial = self.end_state_
            inputs = pd.concat([train.iloc[[-1]], new])  # the last training inputs held up to the new data
        elif t0 > train.index[0]:
            initial = None
            inputs = pd.concat([train[train.index < t0], new])
        else:  # from rest (a single sample gets a rest sample 1 s before it, to make a valid scenario)
            initial = None
            inputs = new if len(new) > 1 else pd.concat([new.assign(speed_rpm=0.0).set_axis([t0 - 1.0]), new])
        readings, _ = cal.predict(self.network_, Scenario(inputs, "inputs"), initial=initial,
                                  reference=self.reference_state_)
        return readings[self.outputs_].to_numpy()[len(inputs) - len(new):]

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        return self.physics(X)


class LPTNHybrid(LPTN):
    """Physics plus a ridge model (``alpha``) of its training residual on temperatures and physics output."""

    def __init__(self, hidden_nodes: int = 2, max_seconds: float = 60.0, max_fit_samples: int = 2500,
                 alpha: float = 10.0, speed_column: str | None = None, ambient_column: str | None = None):
        super().__init__(hidden_nodes, max_seconds, max_fit_samples, speed_column, ambient_column)
        self.alpha = alpha

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"hidden_nodes": 1, "max_seconds": 1.0, "max_fit_samples": 150, "alpha": 1.0},
                {"hidden_nodes": 0, "max_seconds": 1.0, "max_fit_samples": 150, "alpha": 100.0}]

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
        self.residual_model_ = Ridge(alpha=self.alpha, solver="svd").fit((F - self.f_mean_) / self.f_scale_,
                                                                          y - phys)

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        phys = self.physics(X)
        F = (self._features(X, phys) - self.f_mean_) / self.f_scale_
        return phys + self.residual_model_.predict(F).reshape(len(X), -1)


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "lptn", LPTN)
    registry.add("model", "lptn_hybrid", LPTNHybrid)
