"""Model ``ridge_demo``: ridge regression of displacement (µm) on standardised temperatures (°C).

A model class and the hook that registers it; no YAML: ``thermodrift run model=ridge_demo`` builds its config
from the constructor's defaults and ``search_space()``.
"""

from sklearn.linear_model import Ridge
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from thermodrift.core.components import ThermalModel
from thermodrift.core.hookspecs import hookimpl


class RidgeDemo(ThermalModel):
    """y (µm) = b + Σ a_i z_i, z_i the standardised temperatures; ``alpha`` is the L2 penalty."""

    def __init__(self, alpha: float = 1.0):
        self.alpha = alpha

    @classmethod
    def get_test_params(cls):
        return [{"alpha": 1.0}, {"alpha": 1e-3}]

    @classmethod
    def search_space(cls):
        return {"alpha": {"type": "float", "low": 1e-4, "high": 100.0, "log": True}}

    def _fit(self, X, y):
        self.pipeline_ = make_pipeline(StandardScaler(), Ridge(alpha=self.alpha)).fit(X.to_numpy(dtype=float), y)

    def _predict(self, X):
        return self.pipeline_.predict(X.to_numpy(dtype=float))


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "ridge_demo", RidgeDemo)

