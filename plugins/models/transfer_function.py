"""Model ``transfer_function``: the industrial anchor, a linear transfer-function model as CNCs run it today.

Displacement (µm) is a linear read-out of first-order-filtered inputs (Mares et al., Precision Engineering 2020
use the same structure inside the controller): every temperature (°C) raw and low-pass filtered with time
constants ``tau`` geometric between ``tau_min_s`` and ``tau_max_s``, and every drive input (spindle speed, rpm;
cutting power, W) as heat terms (v / v_ref)^p for p in ``powers``, raw and filtered with the same constants.
The read-out is ridge regression on standardised features; its strength is the one of ``alphas`` with the
lowest RMSE on an inner validation fold (the last ``inner_fraction`` of the training rows), then refit on all.

The features are :class:`thermodrift.compensator.features.FeatureStage` (the one home of the filter arithmetic,
shared with the AutoML pipelines and the deployed compensator): the exact discretisation of dx/dt = (u − x)/tau
at the training sampling interval (s), so the model assumes the controller calls it at that interval. The
filters start from the first input row (temperatures) and from rest (drive terms: a machine starts cold and
stopped). That state is the model's memory (``history_length = None``): ``predict(X, history)`` runs the
filters through ``history`` first, and :meth:`TransferFunction.streamer` carries it in a few numpy operations
per row (≤ 0.05 ms).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pandas as pd
from sklearn.linear_model import Ridge

from thermodrift.compensator.features import FeatureStage
from thermodrift.core.components import ThermalModel, per_run, same_run
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.metrics import rmse


class TransferFunction(ThermalModel):
    """First-order-filtered temperatures and drive heat terms with a ridge read-out (see the module docstring)."""

    refits_cheaply = True  # filters and a ridge read-out: a fallback without each sensor is cheap

    extra_input_roles: ClassVar[tuple[str, ...]] = ("speed", "cutting_power", "ambient")
    history_length: ClassVar[int | None] = None
    sparse_targets: ClassVar[bool] = True  # filters at full rate, read-out fitted on the measured rows

    def __init__(self, tau_min_s: float = 300.0, tau_max_s: float = 14400.0, n_taus: int = 4,
                 powers: tuple = (1.0, 2.0), alphas: tuple = (1e-4, 1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3),
                 inner_fraction: float = 0.25):
        self.tau_min_s = tau_min_s
        self.tau_max_s = tau_max_s
        self.n_taus = n_taus
        self.powers = powers
        self.alphas = alphas
        self.inner_fraction = inner_fraction

    @classmethod
    def get_test_params(cls):
        return [{}, {"n_taus": 2, "powers": (1.5,), "alphas": (0.1, 10.0)}]

    @classmethod
    def search_space(cls):
        return {"tau_min_s": {"type": "float", "low": 60.0, "high": 1800.0, "log": True},
                "tau_max_s": {"type": "float", "low": 3600.0, "high": 43200.0, "log": True},
                "n_taus": {"type": "int", "low": 1, "high": 6}}

    # ------------------------------------------------------------------------------------------------ fitting
    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        if not 0 < self.tau_min_s <= self.tau_max_s or self.n_taus < 1:
            raise ValueError("need 0 < tau_min_s <= tau_max_s and n_taus >= 1")
        if not 0 < self.inner_fraction < 1 or not len(self.alphas):
            raise ValueError("inner_fraction must be in (0, 1) and alphas non-empty")
        self.features_ = FeatureStage.fit(X.to_numpy(dtype=float), list(X.columns), X.attrs.get("roles", {}),
                                          np.asarray(X.index, dtype=float),
                                          np.geomspace(self.tau_min_s, self.tau_max_s, self.n_taus), self.powers)
        measured = np.isfinite(y).all(axis=1)
        F, y = self._features(X)[measured], y[measured]
        mean, scale = F.mean(axis=0), F.std(axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        Z = (F - mean) / scale
        cut = int(round(len(Z) * (1 - self.inner_fraction)))
        if 2 <= cut <= len(Z) - 1:
            scores = [rmse(Ridge(alpha=a).fit(Z[:cut], y[:cut]).predict(Z[cut:]), y[cut:])
                      for a in self.alphas]
            self.alpha_ = float(self.alphas[int(np.argmin(scores))])
        else:
            self.alpha_ = float(np.median(self.alphas))
        ridge = Ridge(alpha=self.alpha_).fit(Z, y)
        coef = np.atleast_2d(ridge.coef_)  # (k, features)
        # The standardisation is folded into the read-out, so prediction is one affine map of the features.
        self.weights_ = coef / scale
        self.intercept_ = np.atleast_1d(ridge.intercept_) - self.weights_ @ mean

    def _features(self, X: pd.DataFrame) -> np.ndarray:
        """Filtered features of ``X``, each run's filters started at its own first row."""
        return per_run(X, lambda part: self.features_.transform(part[self.features_.inputs].to_numpy(dtype=float)))

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        return self._features(X) @ self.weights_.T + self.intercept_

    def streamer(self, history: pd.DataFrame | None = None) -> "TransferFunctionStreamer":
        return TransferFunctionStreamer(self, history)

    def export_state(self) -> dict:
        """Runtime ``transfer_function``: the feature stage's state and the affine read-out of its features."""
        return {"runtime": "transfer_function", "inputs": [str(c) for c in self.feature_names_in_],
                "targets": list(self.target_names_), "history_length": None, "features": self.features_.to_state(),
                "weights": self.weights_, "intercept": self.intercept_}


class TransferFunctionStreamer:
    """Carries the filter state (:class:`FeatureStream`); ``update(row)`` costs a handful of numpy operations."""

    def __init__(self, model: TransferFunction, history: pd.DataFrame | None = None):
        stage = model.features_
        self.columns = stage.inputs
        history = same_run(history)
        past = None if history is None or not len(history) else history[self.columns].to_numpy(dtype=float)
        self.stream = stage.stream(past)
        self.weights, self.intercept = model.weights_, model.intercept_

    def update(self, row) -> np.ndarray:
        """Displacement (µm) per target for one new input ``row`` (a mapping column -> value)."""
        return self.weights @ self.stream.update(np.array([row[c] for c in self.columns], dtype=float)) \
            + self.intercept


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "transfer_function", TransferFunction)
