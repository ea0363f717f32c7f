"""Model ``dltk``: deformable convolution -> LSTM -> Transformer encoder -> Fourier-KAN head (study S3's model).

Window of ``window`` rows (°C) -> 1-D deformable convolution (``channels``, kernel ``kernel``, learned fractional
tap offsets; ReLU) -> LSTM (``hidden_size``) -> linear to the attention width (``hidden_size`` rounded up to a
multiple of ``heads``) -> one Transformer encoder layer -> the newest step -> dropout -> Fourier-KAN layer
(``kan_grid`` harmonics) -> displacement (µm).

S3's four ablations switch one stage off and really change the network (``n_parameters()`` differs):
``deform=False`` uses a plain convolution of the same size (no offset branch); ``lstm=False`` replaces the LSTM by
a per-step linear map; ``transformer=False`` drops the encoder; ``kan=False`` uses a linear head.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from thermodrift.core.hookspecs import hookimpl
from thermodrift.plugins.models._sequence import SequenceModel, layers, s3_search_space, transformer_width

if TYPE_CHECKING:
    from torch import nn

# ablation tag -> the switches it sets (S3's ablation table)
ABLATIONS = {"full": {}, "no_deform": {"deform": False}, "no_lstm": {"lstm": False},
             "no_transformer": {"transformer": False}, "no_kan": {"kan": False}}


class DLTK(SequenceModel):
    """Deformable convolution -> LSTM -> Transformer encoder -> Fourier-KAN head (S3's model), °C -> µm.

    ``trainer`` and ``random_state`` as in ``SequenceModel``.
    """

    def __init__(self, channels: int = 16, kernel: int = 3, hidden_size: int = 32, heads: int = 4, kan_grid: int = 4,
                 deform: bool = True, lstm: bool = True, transformer: bool = True, kan: bool = True,
                 window: int = 16, dropout: float = 0.1, trainer: dict | None = None, random_state: int = 0):
        self.channels = channels
        self.kernel = kernel
        self.hidden_size = hidden_size
        self.heads = heads
        self.kan_grid = kan_grid
        self.deform = deform
        self.lstm = lstm
        self.transformer = transformer
        self.kan = kan
        self.window = window
        self.dropout = dropout
        self.trainer = trainer
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        tiny = {"channels": 4, "hidden_size": 8, "heads": 2, "kan_grid": 2, "window": 4,
                "trainer": {"epochs": 4, "t0": 2, "batch_size": 64}}
        return [tiny, {**tiny, "deform": False, "lstm": False, "transformer": False, "kan": False}]

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
        conv = L["DeformableConv1d"] if self.deform else (lambda i, o, k: L["Conv"](i, o, k))
        width = transformer_width(self.hidden_size, self.heads)
        stages: list[nn.Module] = [conv(n_inputs, self.channels, self.kernel), nn.ReLU()]
        stages.append(L["LSTMSequence"](self.channels, self.hidden_size) if self.lstm
                      else nn.Linear(self.channels, self.hidden_size))
        if self.transformer:
            stages += [nn.Linear(self.hidden_size, width), L["encoder"](width, self.heads, self.dropout)]
        out_width = width if self.transformer else self.hidden_size
        stages += [L["LastStep"](), nn.Dropout(self.dropout)]
        stages.append(L["FourierKAN"](out_width, n_outputs, self.kan_grid) if self.kan
                      else nn.Linear(out_width, n_outputs))
        return nn.Sequential(*stages)


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "dltk", DLTK)
