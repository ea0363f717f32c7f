"""Model ``mlr``: multiple linear regression of displacement (µm) on temperatures (°C), optionally ridge.

The standard industrial thermal-error model and the baseline shown beside every other model.
"""

import numpy as np
from sklearn.linear_model import Ridge

from thermodrift.core.components import Streamer, ThermalModel
from thermodrift.core.hookspecs import hookimpl


class MLR(ThermalModel):
    """Least squares y = b + Σ a_i T_i (µm, µm/K); ``alpha`` > 0 adds an L2 penalty on standardised inputs."""

    refits_cheaply = True  # a least-squares solve: a fallback without each sensor costs milliseconds

    def __init__(self, alpha: float = 0.0):
        self.alpha = alpha

    @classmethod
    def get_test_params(cls):
        return [{"alpha": 0.0}, {"alpha": 1.0}]

    @classmethod
    def search_space(cls):
        return {"alpha": {"type": "float", "low": 1e-6, "high": 100.0, "log": True}}

    def _fit(self, X, y):
        x = X.to_numpy(dtype=float)
        self.x_mean_, self.x_scale_ = x.mean(axis=0), x.std(axis=0) + 1e-12
        self.regressor_ = Ridge(alpha=self.alpha, solver="svd").fit((x - self.x_mean_) / self.x_scale_, y)

    def _predict(self, X):
        return self.regressor_.predict((X.to_numpy(dtype=float) - self.x_mean_) / self.x_scale_)

    def streamer(self, history=None) -> "_LinearStreamer":
        return _LinearStreamer(self, history)

    def export_state(self) -> dict:
        """Runtime ``linear``: the ridge read-out on standardised inputs, as ``_predict`` computes it."""
        return {"runtime": "linear", "inputs": [str(c) for c in self.feature_names_in_],
                "targets": list(self.target_names_), "history_length": 0, "mean": self.x_mean_,
                "scale": self.x_scale_, "coef": np.asarray(self.regressor_.coef_, dtype=float).reshape(
                    len(self.target_names_), -1).T, "intercept": np.atleast_1d(self.regressor_.intercept_)}


class _LinearStreamer(Streamer):
    """Memoryless: one dot product per row with the coefficients in °C units."""

    def __init__(self, model: MLR, history=None):
        super().__init__(model, None)
        coef = np.asarray(model.regressor_.coef_, dtype=float).reshape(-1, len(self.columns))
        self.weights = (coef / model.x_scale_).T
        self.bias = np.asarray(model.regressor_.intercept_, dtype=float).reshape(-1) - model.x_mean_ @ self.weights

    def update(self, row) -> np.ndarray:
        return self.values(row) @ self.weights + self.bias


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "mlr", MLR)
