"""Model ``lstm``: S1's long short-term memory network over a sliding window of temperatures.

Each prediction reads the last ``window`` input rows (S1: 5) through one LSTM layer of ``hidden_units`` units
(S1 searched 1–200) and a linear head on the last step's output; inputs and targets are Z-scored, the loss is
MSE and training stops after at most ``epochs`` (S1: 200). Training runs on the shared trainer: AdamW with SGDR
warm restarts, gradient clipping and early stopping on the chronological validation tail, where S1 used plain
Adam at a fixed learning rate; the trainer's ``lr_max`` (``trainer__lr_max``) spans S1's 0.01–0.15 and is the
peak of each SGDR cycle. The defaults (32 units, 0.01) are an untuned choice, S1's baseline LSTM; S1's PSO found
45 units and 0.0941.

The window is the model's memory (``history_length = window − 1``): ``predict(X, history)`` fills the first
rows' windows from ``history``; without history the first row is repeated (as at a cold start).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.training import TrainerSettings
from thermodrift.plugins.models._sequence import SequenceModel

if TYPE_CHECKING:
    from torch import nn


class LSTM(SequenceModel):
    """Temperatures (°C) over the last ``window`` samples → displacements (µm) (see the module docstring)."""

    trainer_defaults = TrainerSettings(lr_max=0.01, weight_decay=0.0, epochs=200, batch_size=None, t0=50, t_mult=2)

    def __init__(self, window: int = 5, hidden_units: int = 32, trainer: dict | None = None, random_state: int = 0):
        self.window = window
        self.hidden_units = hidden_units
        self.trainer = trainer
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        return [{"hidden_units": 4, "trainer": {"epochs": 6, "t0": 2, "lr_max": 0.05}},
                {"window": 3, "hidden_units": 2,
                 "trainer": {"lr_max": 0.1, "epochs": 4, "t0": 2, "t_mult": 1, "batch_size": 64, "patience": None}}]

    @classmethod
    def search_space(cls):
        return {"trainer__lr_max": {"type": "float", "low": 0.01, "high": 0.15},
                "hidden_units": {"type": "int", "low": 1, "high": 200}}

    def _network(self, n_inputs: int, n_outputs: int) -> nn.Module:
        from thermodrift.compensator.networks import LSTMNet  # one home: the runtime rebuilds the same network

        if self.hidden_units < 1:
            raise ValueError(f"hidden_units must be >= 1, got {self.hidden_units}")
        return LSTMNet(n_inputs, int(self.hidden_units), n_outputs)

    def export_state(self) -> dict:
        """Runtime ``sequence`` (architecture ``lstm``): the weights as torch tensors and the scalers."""
        return {"runtime": "sequence", "architecture": "lstm", "inputs": [str(c) for c in self.feature_names_in_],
                "targets": list(self.target_names_), "history_length": self.history_length,
                "window": int(self.window), "hidden_units": int(self.hidden_units),
                "n_inputs": len(self.x_scaler_.mean), "n_outputs": len(self.y_scaler_.mean),
                "weights": dict(self.state_dict_), "x_mean": np.asarray(self.x_scaler_.mean),
                "x_scale": np.asarray(self.x_scaler_.scale), "y_mean": np.asarray(self.y_scaler_.mean),
                "y_scale": np.asarray(self.y_scaler_.scale)}


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "lstm", LSTM)
