"""Template: a thermodrift model plugin (temperatures in °C -> displacement in µm) in one file.

How to use:
1. Copy this file into your package, e.g. ``my_thermal_models/elm.py``, and rename class and registry name.
2. Fill in the ``todo`` parts. Keep the rules: ``__init__`` only stores its arguments; ``_fit`` learns and
   stores fitted attributes ending in ``_``; ``_predict`` returns (n_samples, n_channels) in µm; every random
   thing takes ``random_state``.
3. One entry-point line in your ``pyproject.toml``::

       [project.entry-points.thermodrift]
       elm = "my_thermal_models.elm"

4. ``thermodrift run model=elm`` works with no YAML: its config is built from the registry
   (``params`` = the constructor's defaults). For other defaults ship ``my_thermal_models/conf/model/elm.yaml``
   and add ``registry.add_searchpath("pkg://my_thermal_models.conf")`` in a ``thermodrift_hydra_searchpaths`` hook.
5. Check it: ``from thermodrift.testing import check_component; check_component("model", "elm")``
   or subclass ``thermodrift.testing.pytest_components.ModelTests`` with ``name = "elm"`` in your tests.

The example is an extreme learning machine: a fixed random tanh layer and a ridge read-out.
"""

import numpy as np

from thermodrift.core.components import ThermalModel
from thermodrift.core.hookspecs import hookimpl


# todo: rename the class and write what it models, with units
class ExtremeLearningMachine(ThermalModel):
    """y (µm) = ridge read-out of tanh(z W + b), z the standardised temperatures, W and b random and fixed."""

    # todo: one argument per hyperparameter, with defaults; store each unchanged under its own name
    def __init__(self, n_hidden: int = 32, alpha: float = 1e-2, random_state: int | None = None):
        self.n_hidden = n_hidden
        self.alpha = alpha
        self.random_state = random_state

    # todo: at least two cheap parameter sets; the conformance suite runs every check with each
    @classmethod
    def get_test_params(cls):
        return [{"n_hidden": 8, "random_state": 0}, {"n_hidden": 16, "alpha": 1.0, "random_state": 1}]

    # todo: the default Optuna search space; only constructor arguments
    @classmethod
    def search_space(cls):
        return {"n_hidden": {"type": "int", "low": 4, "high": 128, "log": True},
                "alpha": {"type": "float", "low": 1e-4, "high": 10.0, "log": True}}

    # todo: learn from X (DataFrame, °C) and y (ndarray (n, k), µm); store fitted attributes ending in "_"
    def _fit(self, X, y):
        x = X.to_numpy(dtype=float)
        self.x_mean_, self.x_scale_ = x.mean(axis=0), x.std(axis=0) + 1e-12
        rng = np.random.default_rng(self.random_state)
        self.weights_ = rng.normal(0.0, 1.0, (x.shape[1], self.n_hidden))
        self.bias_ = rng.uniform(-1.0, 1.0, self.n_hidden)
        h = self._hidden(x)
        self.y_mean_ = y.mean(axis=0)
        self.readout_ = np.linalg.solve(h.T @ h + self.alpha * np.eye(self.n_hidden), h.T @ (y - self.y_mean_))

    # todo: return predictions of shape (n_samples, n_channels) in µm
    def _predict(self, X):
        return self._hidden(X.to_numpy(dtype=float)) @ self.readout_ + self.y_mean_

    def _hidden(self, x):
        return np.tanh(((x - self.x_mean_) / self.x_scale_) @ self.weights_ + self.bias_)


# todo: the registry name users type in `thermodrift run model=<name>`
@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "elm", ExtremeLearningMachine)

