"""Model ``cnn_lstm_transformer``: convolution, LSTM and a Transformer encoder in series (an S3 baseline).

Window (°C) -> Conv1d (``channels``, ReLU) -> LSTM (``hidden_size``) -> linear to the attention width (``hidden_size``
rounded up to a multiple of ``heads``) -> one Transformer encoder layer (``heads`` heads) -> newest step -> linear
-> displacement (µm). DLTK without its deformable convolution and Fourier-KAN head.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from thermodrift.core.hookspecs import hookimpl
from thermodrift.plugins.models._sequence import SequenceModel, layers, s3_search_space, transformer_width

if TYPE_CHECKING:
    from torch import nn


class CNNLSTMTransformer(SequenceModel):
    """Convolution, LSTM and a Transformer encoder in series over the input window (°C), -> µm (an S3 baseline).

    ``trainer`` and ``random_state`` as in ``SequenceModel``.
    """

    def __init__(self, channels: int = 16, kernel: int = 3, hidden_size: int = 32, heads: int = 4,
                 window: int = 16, dropout: float = 0.1, trainer: dict | None = None, random_state: int = 0):
        self.channels = channels
        self.kernel = kernel
        self.hidden_size = hidden_size
        self.heads = heads
        self.window = window
        self.dropout = dropout
        self.trainer = trainer
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        return [{"channels": 4, "hidden_size": 8, "heads": 2, "window": 4,
                 "trainer": {"epochs": 4, "t0": 2, "batch_size": 64}}]

    @classmethod
    def search_space(cls):
        return {
            "hidden_size": {"type": "int", "low": 32, "high": 128},
            "heads": {"type": "int", "low": 2, "high": 8},
            **s3_search_space(),
        }

    def _network(self, n_inputs: int, n_outputs: int) -> nn.Module:
        from torch import nn

        L = layers()
        width = transformer_width(self.hidden_size, self.heads)
        return nn.Sequential(L["Conv"](n_inputs, self.channels, self.kernel), nn.ReLU(),
                             L["LSTMSequence"](self.channels, self.hidden_size), nn.Linear(self.hidden_size, width),
                             L["encoder"](width, self.heads, self.dropout), L["LastStep"](),
                             nn.Linear(width, n_outputs))


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "cnn_lstm_transformer", CNNLSTMTransformer)
