"""Model ``bp``: the back-propagation network (multilayer perceptron) of the seed studies.

S2 maps five sensitive temperatures to spindle drift with two hidden layers of 8 tanh units (tried 3–13);
S1 uses a BP network as a baseline. Here it is trained by the shared trainer (AdamW, SGDR warm restarts,
gradient clipping, early stopping on the chronological validation tail), so the stabilisers are searched
together with the hidden structure.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.training import TorchThermalModel, trainer_search_space

if TYPE_CHECKING:
    from torch import nn

# activation -> its torch.nn class name (torch is imported when a network is built, not with the plugin)
ACTIVATIONS = {"tanh": "Tanh", "sigmoid": "Sigmoid", "relu": "ReLU", "gelu": "GELU"}


class BPNetwork(TorchThermalModel):
    """Temperatures (°C) → displacements (µm) through ``hidden_layers`` layers of ``hidden_units`` units.

    Inputs and targets are Z-scored inside the trainer; the output layer is linear. ``trainer`` overrides the
    trainer's settings (:class:`~thermodrift.core.training.TrainerSettings`: SGDR ``lr_max``, ``t0``,
    ``t_mult``, ``eta_min_ratio``, ``clip_norm``, ``epochs``, ...); ``random_state`` seeds weights and batches.
    """

    def __init__(self, hidden_layers: int = 2, hidden_units: int = 8, activation: str = "tanh",
                 trainer: dict | None = None, random_state: int = 0):
        self.hidden_layers = hidden_layers
        self.hidden_units = hidden_units
        self.activation = activation
        self.trainer = trainer
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        return [
            {"hidden_units": 4, "trainer": {"epochs": 6, "t0": 2, "t_mult": 2}},
            {"hidden_layers": 1, "hidden_units": 3, "activation": "relu",
             "trainer": {"epochs": 4, "batch_size": 32, "t0": 2, "t_mult": 1, "clip_norm": None, "patience": None}},
        ]

    @classmethod
    def search_space(cls):
        return {
            "hidden_layers": {"type": "int", "low": 1, "high": 3},
            "hidden_units": {"type": "int", "low": 3, "high": 13},
            **trainer_search_space(),  # trainer__lr_max, trainer__t0, ...: tuned together with the structure
        }

    def _build(self, n_inputs: int, n_outputs: int) -> nn.Module:
        from torch import nn

        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation must be one of {sorted(ACTIVATIONS)}, got {self.activation!r}")
        if self.hidden_layers < 0 or self.hidden_units < 1:
            raise ValueError("hidden_layers must be >= 0 and hidden_units >= 1")
        layers: list[nn.Module] = []
        width = n_inputs
        for _ in range(self.hidden_layers):
            layers += [nn.Linear(width, self.hidden_units), getattr(nn, ACTIVATIONS[self.activation])()]
            width = self.hidden_units
        layers.append(nn.Linear(width, n_outputs))
        return nn.Sequential(*layers)


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "bp", BPNetwork)
