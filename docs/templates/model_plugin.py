"""Template: a thermodrift torch model plugin (temperatures in °C -> displacement in µm) in one file.

How to use:
1. Copy this file into your package, e.g. ``my_thermal_models/residual_mlp.py``, and rename class and
   registry name.
2. Fill in the ``todo`` parts. A torch model states only its own hyper-parameters, then ``trainer=None`` and
   ``random_state=0``, and stores each unchanged; ``_build(n_inputs, n_outputs)`` returns the network. The
   shared trainer (``thermodrift.core.training``: Z-scoring, AdamW, SGDR warm restarts, gradient clipping,
   early stopping, divergence guard, Optuna pruning) trains it. ``trainer`` overrides its settings
   (``TrainerSettings``), e.g. ``trainer={"epochs": 100}``; they are nested parameters ``trainer__epochs``,
   ``trainer__lr_max``, ... for ``get_params``/``set_params``, search spaces and
   ``thermodrift run model=residual_mlp model.params.trainer.epochs=100``. To change the defaults for this
   model, set ``trainer_defaults = TrainerSettings(epochs=100)`` on the class. Sequence models override
   ``_inputs(X)`` to return windows shaped (n, window, features).
   (A model without torch subclasses ``thermodrift.core.components.ThermalModel`` and implements
   ``_fit(X, y)`` and ``_predict(X)``; see the README's ``my_ridge``.)
3. One entry-point line in your ``pyproject.toml``::

       [project.entry-points.thermodrift]
       residual_mlp = "my_thermal_models.residual_mlp"

4. ``thermodrift run model=residual_mlp`` works with no YAML: its config is built from the registry
   (``params`` = the constructor's defaults). For other defaults ship ``my_thermal_models/conf/model/residual_mlp.yaml``
   and add ``registry.add_searchpath("pkg://my_thermal_models.conf")`` in a ``thermodrift_hydra_searchpaths`` hook.
5. Check it: ``from thermodrift.testing import check_component; check_component("model", "residual_mlp")``
   or subclass ``thermodrift.testing.pytest_components.ModelTests`` with ``name = "residual_mlp"`` in your tests.

The example is a residual MLP: a linear thermal law plus a small tanh network for the nonlinear remainder.
"""

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.training import TorchThermalModel, trainer_search_space


# todo: rename the class and write what it models, with units
class ResidualMLP(TorchThermalModel):
    """y (µm) = A z + MLP(z), z the standardised temperatures (°C); the MLP has one tanh layer of ``hidden_units``."""

    # todo: your own hyper-parameters with defaults, then trainer and random_state; store each unchanged
    def __init__(self, hidden_units: int = 8, trainer: dict | None = None, random_state: int = 0):
        self.hidden_units = hidden_units
        self.trainer = trainer
        self.random_state = random_state

    # todo: at least two cheap parameter sets (few epochs); the conformance suite runs every check with each
    @classmethod
    def get_test_params(cls):
        return [{"hidden_units": 4, "trainer": {"epochs": 6, "t0": 2}},
                {"hidden_units": 2, "trainer": {"epochs": 4, "t0": 2, "t_mult": 1, "batch_size": 32}}]

    # todo: the default Optuna search space: your parameters plus, if you like, the trainer's stabilisers
    @classmethod
    def search_space(cls):
        return {"hidden_units": {"type": "int", "low": 2, "high": 32, "log": True}, **trainer_search_space()}

    # todo: the network from n_inputs standardised temperatures to n_outputs standardised displacements
    def _build(self, n_inputs, n_outputs):
        from torch import nn  # imported here so that listing plugins does not import torch

        class Residual(nn.Module):
            def __init__(self, hidden_units):
                super().__init__()
                self.linear = nn.Linear(n_inputs, n_outputs)
                self.mlp = nn.Sequential(nn.Linear(n_inputs, hidden_units), nn.Tanh(),
                                         nn.Linear(hidden_units, n_outputs))

            def forward(self, x):
                return self.linear(x) + self.mlp(x)

        return Residual(self.hidden_units)


# todo: the registry name users type in `thermodrift run model=<name>`
@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "residual_mlp", ResidualMLP)
