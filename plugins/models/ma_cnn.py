"""Model ``ma_cnn``: a multi-attention convolutional network (an S3 baseline).

Window (°C) -> two 1-D convolutions (``channels``, kernel ``kernel``, ReLU) -> channel attention (squeeze and
excitation) -> temporal attention pooling over the window -> dropout -> linear -> displacement (µm).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from thermodrift.core.hookspecs import hookimpl
from thermodrift.plugins.models._sequence import SequenceModel, layers, s3_search_space

if TYPE_CHECKING:
    from torch import nn


class MultiAttentionCNN(SequenceModel):
    """A multi-attention convolutional network over the input window (°C), -> µm (an S3 baseline).

    ``trainer`` and ``random_state`` as in ``SequenceModel``.
    """

    def __init__(self, channels: int = 32, kernel: int = 3,
                 window: int = 16, dropout: float = 0.1, trainer: dict | None = None, random_state: int = 0):
        self.channels = channels
        self.kernel = kernel
        self.window = window
        self.dropout = dropout
        self.trainer = trainer
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        return [{"channels": 4, "window": 4, "trainer": {"epochs": 4, "t0": 2, "batch_size": 64}}]

    @classmethod
    def search_space(cls):
        return {
            "channels": {"type": "int", "low": 16, "high": 64},
            **s3_search_space(),
        }

    def _network(self, n_inputs: int, n_outputs: int) -> nn.Module:
        from torch import nn

        L = layers()
        return nn.Sequential(L["Conv"](n_inputs, self.channels, self.kernel), nn.ReLU(),
                             L["Conv"](self.channels, self.channels, self.kernel), nn.ReLU(),
                             L["ChannelAttention"](self.channels), L["TemporalAttention"](self.channels),
                             nn.Dropout(self.dropout), nn.Linear(self.channels, n_outputs))


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "ma_cnn", MultiAttentionCNN)
