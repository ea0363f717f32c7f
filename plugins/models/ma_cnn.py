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
    """See the module docstring. Trainer fields (``lr_max``, ``loss``, ``epochs``, ...) as in ``bp``."""

    def __init__(self, channels: int = 32, kernel: int = 3,
                 window: int = 16, dropout: float = 0.1, lr_max: float = 3e-3, loss: str = "mse", epochs: int = 60,
                 batch_size: int | None = 128, t0: int = 10, t_mult: int = 2, patience: int | None = 3,
                 weight_decay: float = 1e-4, random_state: int = 0, device: str = "auto"):
        self.channels = channels
        self.kernel = kernel
        self.window = window
        self.dropout = dropout
        self.lr_max = lr_max
        self.loss = loss
        self.epochs = epochs
        self.batch_size = batch_size
        self.t0 = t0
        self.t_mult = t_mult
        self.patience = patience
        self.weight_decay = weight_decay
        self.random_state = random_state
        self.device = device

    @classmethod
    def get_test_params(cls):
        return [{"channels": 4, "window": 4, "epochs": 4, "t0": 2, "batch_size": 64}]

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
