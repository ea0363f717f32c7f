"""Model ``mnr``: multivariate nonlinear regression, S1's polynomial baseline.

Displacement (µm) as a second-order polynomial of the temperatures (°C): every T_i, every T_i², every product
T_i·T_j, on standardised inputs, fitted by ridge regression (``alpha`` > 0 keeps the quadratic terms from
blowing up outside the training range).
"""

from sklearn.linear_model import Ridge
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import PolynomialFeatures, StandardScaler

from thermodrift.core.components import ThermalModel
from thermodrift.core.hookspecs import hookimpl


class MNR(ThermalModel):
    """y = b + Σ a_i T_i + Σ_{i≤j} c_ij T_i T_j (µm), ridge penalty ``alpha`` on the standardised terms."""

    automl_cost = "cheap"
    # no feature stage in AutoML: the polynomial expansion of many filtered columns is slow and ill-conditioned
    automl_features = False

    def __init__(self, degree: int = 2, alpha: float = 1.0):
        self.degree = degree
        self.alpha = alpha

    @classmethod
    def get_test_params(cls):
        return [{"alpha": 1.0}, {"degree": 3, "alpha": 0.1}]

    @classmethod
    def search_space(cls):
        return {"alpha": {"type": "float", "low": 1e-4, "high": 100.0, "log": True}}

    def _fit(self, X, y):
        if self.degree < 1:
            raise ValueError(f"degree must be >= 1, got {self.degree}")
        self.pipeline_ = make_pipeline(StandardScaler(), PolynomialFeatures(self.degree, include_bias=False),
                                       StandardScaler(), Ridge(alpha=self.alpha, solver="svd"))
        self.pipeline_.fit(X.to_numpy(dtype=float), y)

    def _predict(self, X):
        return self.pipeline_.predict(X.to_numpy(dtype=float))


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "mnr", MNR)
