"""Base classes for selectors and models, scikit-learn style.

Constructors only store parameters; ``fit`` learns (fitted attributes end in ``_``) and returns ``self``.
Inputs are pandas DataFrames indexed by time in s: temperatures in °C as ``X``, displacements in µm as ``y``
(one column per displacement channel). ``get_test_params`` gives cheap parameter sets for
``thermodrift.testing``; ``search_space`` gives the default Optuna search space (see ``search_space.py``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin


class Component(BaseEstimator):
    """Common surface of selectors and models."""

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        """At least one cheap parameter set for the conformance suite."""
        return [{}]

    @classmethod
    def search_space(cls) -> dict[str, dict[str, Any]]:
        """Default Optuna search space, e.g. ``{"alpha": {"type": "float", "low": 1e-6, "high": 1, "log": True}}``."""
        return {}


class Selector(Component):
    """Picks temperature-sensitive points. ``fit(X °C, y µm)`` sets ``selected_`` (a list of column names)."""

    def fit(self, X: pd.DataFrame, y: pd.DataFrame) -> "Selector":
        self.selected_ = list(self._select(X, y))
        if not self.selected_ or not set(self.selected_) <= set(X.columns):
            raise ValueError(f"{type(self).__name__} returned an invalid selection {self.selected_!r}")
        return self

    def transform(self, X: pd.DataFrame) -> pd.DataFrame:
        """The selected columns of ``X``."""
        return X[self.selected_]

    def fit_transform(self, X: pd.DataFrame, y: pd.DataFrame) -> pd.DataFrame:
        return self.fit(X, y).transform(X)

    def _select(self, X: pd.DataFrame, y: pd.DataFrame) -> list[str]:
        raise NotImplementedError


LAG_PREFIX = "lag1:"


class ThermalModel(RegressorMixin, Component):
    """Maps temperatures (°C) to displacements (µm).

    ``predict(X)`` returns an array of shape (n_samples, n_displacement_channels) in µm. ``X`` holds the
    selected temperature columns, then the channels of every role in ``extra_input_roles`` (e.g. ``("speed",)``
    for a physics model; rpm), then, for models that read the previous measured displacement (a reference, not
    a compensation model: ``uses_target_history``), columns ``lag1:<channel>`` in µm. ``study.model_inputs``
    builds it.
    """

    uses_target_history: ClassVar[bool] = False
    extra_input_roles: ClassVar[tuple[str, ...]] = ()

    def fit(self, X: pd.DataFrame, y: pd.DataFrame) -> "ThermalModel":
        y2 = _as_2d(y)
        self.n_features_in_ = X.shape[1]
        self.feature_names_in_ = np.asarray(X.columns, dtype=object)
        self.target_names_ = list(y.columns) if isinstance(y, pd.DataFrame) else [f"y{i}" for i in range(y2.shape[1])]
        self._fit(X, y2)
        return self

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        out = np.asarray(self._predict(X), dtype=float)
        return out.reshape(len(X), -1)

    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        raise NotImplementedError

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        raise NotImplementedError


def _as_2d(y: pd.DataFrame | np.ndarray) -> np.ndarray:
    arr = np.asarray(y, dtype=float)
    return arr.reshape(len(arr), -1)
