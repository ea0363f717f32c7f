"""Model ``tcn_lstm``: a temporal convolutional network feeding an LSTM (an S3 baseline).

Window (°C) -> ``levels`` TCN residual blocks (dilated causal convolutions, dilation 1, 2, 4, ...; ``channels``,
kernel ``kernel``) -> LSTM (``hidden_size``) -> newest step -> linear -> displacement (µm).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from thermodrift.core.hookspecs import hookimpl
from thermodrift.plugins.models._sequence import SequenceModel, layers, s3_search_space

if TYPE_CHECKING:
    from torch import nn


class TCNLSTM(SequenceModel):
    """A temporal convolutional network over the input window (°C) feeding an LSTM, -> µm (an S3 baseline).

    ``trainer`` and ``random_state`` as in ``SequenceModel``.
    """

    def __init__(self, channels: int = 16, kernel: int = 3, levels: int = 2, hidden_size: int = 32,
                 window: int = 16, dropout: float = 0.1, trainer: dict | None = None, random_state: int = 0):
        self.channels = channels
        self.kernel = kernel
        self.levels = levels
        self.hidden_size = hidden_size
        self.window = window
        self.dropout = dropout
        self.trainer = trainer
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        return [{"channels": 4, "levels": 1, "hidden_size": 8, "window": 4,
                 "trainer": {"epochs": 4, "t0": 2, "batch_size": 64}}]

    @classmethod
    def search_space(cls):
        return {
            "hidden_size": {"type": "int", "low": 32, "high": 128},
            **s3_search_space(),
        }

    def _network(self, n_inputs: int, n_outputs: int) -> nn.Module:
        from torch import nn

        L = layers()
        blocks = [L["TemporalBlock"](n_inputs if i == 0 else self.channels, self.channels, self.kernel, 2 ** i,
                                     self.dropout) for i in range(self.levels)]
        return nn.Sequential(*blocks, L["LSTMSequence"](self.channels, self.hidden_size), L["LastStep"](),
                             nn.Linear(self.hidden_size, n_outputs))


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "tcn_lstm", TCNLSTM)
