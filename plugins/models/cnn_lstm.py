"""Model ``cnn_lstm``: a 1-D convolution over the input window feeding an LSTM (an S3 baseline).

Window of ``window`` rows (°C) -> Conv1d (``channels``, kernel ``kernel``, ReLU) -> LSTM (``hidden_size``) -> the
newest step -> dropout -> linear -> displacement (µm). Trained by the shared trainer; see ``_sequence``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from thermodrift.core.hookspecs import hookimpl
from thermodrift.plugins.models._sequence import SequenceModel, layers, s3_search_space

if TYPE_CHECKING:
    from torch import nn


class CNNLSTM(SequenceModel):
    """A 1-D convolution over the input window (°C) feeding an LSTM, -> µm (an S3 baseline).

    ``trainer`` and ``random_state`` as in ``SequenceModel``.
    """

    def __init__(self, channels: int = 16, kernel: int = 3, hidden_size: int = 32,
                 window: int = 16, dropout: float = 0.1, trainer: dict | None = None, random_state: int = 0):
        self.channels = channels
        self.kernel = kernel
        self.hidden_size = hidden_size
        self.window = window
        self.dropout = dropout
        self.trainer = trainer
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        return [{"channels": 4, "hidden_size": 8, "window": 4, "trainer": {"epochs": 4, "t0": 2, "batch_size": 64}}]

    @classmethod
    def search_space(cls):
        return {
            "hidden_size": {"type": "int", "low": 32, "high": 128},
            **s3_search_space(),
        }

    def _network(self, n_inputs: int, n_outputs: int) -> nn.Module:
        from torch import nn

        L = layers()
        return nn.Sequential(L["Conv"](n_inputs, self.channels, self.kernel), nn.ReLU(),
                             L["LSTMSequence"](self.channels, self.hidden_size), L["LastStep"](),
                             nn.Dropout(self.dropout), nn.Linear(self.hidden_size, n_outputs))


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "cnn_lstm", CNNLSTM)
