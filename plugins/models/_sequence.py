"""Shared parts of the sequence models (S1's ``lstm``; S3's ``cnn_lstm``, ``ma_cnn``, ``cnn_lstm_transformer``,
``tcn_lstm``, ``dltk``): windows over past inputs, their streamer, the S3 search space, and the layers no library
ships.

A prediction for row t reads the input rows t-window+1 .. t (temperatures in °C, Z-scored by the trainer), so
``history_length = window - 1``. Rows before the first one available repeat it (edge padding), at training and
prediction alike. ``predict(X, history)`` and ``streamer(history).update(row)`` give the same numbers; the
streamer keeps the last ``window`` rows, Z-scored once, in a ring buffer and runs one forward pass of the window per
update. torch is imported where a network is built, not with the plugin.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from thermodrift.core.components import Streamer, per_run, same_run
from thermodrift.core.training import (TorchThermalModel, TrainerSettings, predict, resolve_device,
                                       trainer_search_space)

if TYPE_CHECKING:
    from torch import nn


def windows(x: np.ndarray, window: int) -> np.ndarray:
    """(n, features) -> (n, window, features): row t holds rows t-window+1 .. t, the first row repeated before it."""
    x = np.asarray(x, dtype=float)
    padded = np.concatenate([np.repeat(x[:1], window - 1, axis=0), x]) if len(x) else x
    view = np.lib.stride_tricks.sliding_window_view(padded, window, axis=0)  # (n, features, window)
    return np.ascontiguousarray(view.transpose(0, 2, 1))


def s3_search_space() -> dict[str, dict[str, Any]]:
    """S3's search space: learning rate 1e-5..1e-2 (``trainer__lr_max``), dropout, loss in {rmse, mse, mae}
    (``trainer__loss``); models add their sizes."""
    return {
        "trainer__lr_max": {**trainer_search_space()["trainer__lr_max"], "low": 1e-5, "high": 1e-2},
        "dropout": {"type": "float", "low": 0.0, "high": 0.5},
        "trainer__loss": {"type": "categorical", "choices": ["rmse", "mse", "mae"]},
    }


class SequenceModel(TorchThermalModel):
    """Base of the windowed torch models: ``window`` rows in, one displacement row (µm) out per target.

    Subclasses store their constructor parameters (their own plus ``window``, ``trainer`` and ``random_state``,
    see :class:`~thermodrift.core.training.TorchThermalModel`) and implement ``_network(n_inputs, n_outputs)``
    taking (batch, window, inputs).
    """

    # Sized for a CPU (window 16, at most 60 epochs, batches of 128): DLTK's fit on 3,277 rows of the S3 recording
    # takes 40 CPU-seconds on one core (benchmarks/bench_s3_models.py).
    trainer_defaults = TrainerSettings(lr_max=3e-3, weight_decay=1e-4, epochs=60, batch_size=128, t0=10, t_mult=2,
                                       patience=3, loss="mse")

    sparse_targets = True  # windows over every input row; the trainer keeps the windows of measured rows

    @property
    def history_length(self) -> int:  # type: ignore[override]  # depends on the window parameter
        return int(self.window) - 1

    def _inputs(self, X: pd.DataFrame) -> np.ndarray:
        """Windows per row, each run's windows padded with its own first row (none reaches into another run)."""
        if self.window < 1:
            raise ValueError(f"window must be >= 1, got {self.window}")
        return per_run(X, lambda part: windows(part.to_numpy(dtype=float), int(self.window)))

    def _build(self, n_inputs: int, n_outputs: int) -> nn.Module:
        return self._network(n_inputs, n_outputs)

    def _module(self) -> nn.Module:
        """The fitted network in evaluation mode. The trainer's ``_predict`` rebuilds it per call; a streamer calls
        once per row, so the built network is kept (for the current weights only) and left out of pickles."""
        cached = getattr(self, "_network_cache", None)
        device_name = self.trainer_settings().device
        if cached is None or cached[0] is not self.state_dict_ or cached[3] != device_name:
            import torch

            with torch.random.fork_rng(devices=[]):  # building re-initialises weights; keep the caller's RNG intact
                module = self._build(len(self.x_scaler_.mean), len(self.y_scaler_.mean))
            module.load_state_dict(self.state_dict_)
            device = resolve_device(device_name)
            cached = self._network_cache = (self.state_dict_, module.to(device).eval(), device, device_name)
        return cached[1]

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        module = self._module()
        return predict(module, self._inputs(X), self.x_scaler_, self.y_scaler_, self._network_cache[2])

    def streamer(self, history: pd.DataFrame | None = None) -> "SequenceStreamer":
        return SequenceStreamer(self, history)

    def __getstate__(self):
        state = dict(super().__getstate__())  # a copy: object.__getstate__ returns the instance's own __dict__
        state.pop("_network_cache", None)
        return state

    def _network(self, n_inputs: int, n_outputs: int) -> nn.Module:
        raise NotImplementedError

    def n_parameters(self) -> int:
        """Trainable parameters of the fitted network."""
        return int(self.train_report_.n_parameters)


class SequenceStreamer(Streamer):
    """One row per :meth:`update` for a :class:`SequenceModel`: the last ``window`` input rows, Z-scored once, in a
    ring buffer (the oldest row repeated until ``window`` rows have been seen, as :func:`windows` pads), and one
    forward pass of that window per update. Equals ``predict(rows, history)`` (the conformance suite checks it).

    The ring is stored twice over (each row written at ``i`` and ``i + window``), so the window in time order is
    always one contiguous slice: no copy before the forward pass."""

    def __init__(self, model: SequenceModel, history: pd.DataFrame | None = None):
        import torch

        super().__init__(model, None)
        self._torch = torch
        self.module = model._module()
        self.device = model._network_cache[2]
        self.mean, self.scale = model.x_scaler_.mean, model.x_scaler_.scale
        self.y_mean, self.y_scale = model.y_scaler_.mean, model.y_scaler_.scale
        self.window = int(model.window)
        self.ring = np.zeros((2 * self.window, len(self.columns)), dtype=np.float32)
        self.head = 0  # position of the oldest row
        self.seen = 0
        past = model._relevant_history(same_run(history))
        for row in ([] if past is None else past[self.columns].to_numpy(dtype=float)):
            self._push(row)

    def _push(self, x: np.ndarray) -> None:
        z = (x - self.mean) / self.scale  # float64, rounded to float32 on storing, as the batch path does
        if self.seen == 0:  # edge padding: the first row fills the whole window
            self.ring[:] = z
        else:
            self.ring[self.head] = self.ring[self.head + self.window] = z
            self.head = (self.head + 1) % self.window
        self.seen += 1

    def update(self, row) -> np.ndarray:
        """Displacement (µm) per target for one new input ``row`` (see :meth:`Streamer.update`)."""
        self._push(self.values(row))
        window = self._torch.from_numpy(self.ring[self.head:self.head + self.window])[None].to(self.device)
        with self._torch.inference_mode():
            out = self.module(window)[0].cpu().numpy()
        return out.astype(float) * self.y_scale + self.y_mean


def transformer_width(size: int, heads: int) -> int:
    """The smallest multiple of ``heads`` that is >= ``size`` (attention splits d_model across heads)."""
    return heads * math.ceil(size / heads)


# ---------------------------------------------------------------------------------------------------- layers
def layers():
    """The hand-written layers (built on first use, so importing the plugin does not import torch)."""
    global _LAYERS
    if _LAYERS is None:
        _LAYERS = _define_layers()
    return _LAYERS


_LAYERS = None


def _define_layers():
    import torch
    from torch import nn

    class LastStep(nn.Module):
        """(batch, time, features) -> (batch, features) at the newest time step."""

        def forward(self, x):
            return x[:, -1]

    class LSTMSequence(nn.Module):
        """An LSTM that returns its whole output sequence (batch, time, hidden)."""

        def __init__(self, n_in: int, hidden: int):
            super().__init__()
            self.lstm = nn.LSTM(n_in, hidden, batch_first=True)

        def forward(self, x):
            return self.lstm(x)[0]

    class Conv(nn.Module):
        """1-D convolution on (batch, time, channels) with 'same' length; ``causal`` pads only the past."""

        def __init__(self, n_in: int, n_out: int, kernel: int, dilation: int = 1, causal: bool = False):
            super().__init__()
            self.pad = (kernel - 1) * dilation
            self.causal = causal
            self.conv = nn.Conv1d(n_in, n_out, kernel, dilation=dilation)

        def forward(self, x):
            x = x.transpose(1, 2)
            left = self.pad if self.causal else self.pad // 2
            x = nn.functional.pad(x, (left, self.pad - left), mode="replicate")
            return self.conv(x).transpose(1, 2)

    class DeformableConv1d(nn.Module):
        """1-D deformable convolution (Dai et al. 2017, in one dimension): each output step t reads its kernel
        taps at t + (k - K//2) + delta(t, k), with learned fractional offsets delta from a plain convolution
        (zero-initialised, so training starts from an ordinary convolution), by linear interpolation;
        positions outside the window take the nearest edge value. torchvision's deform_conv2d is 2-D and not a
        dependency, hence written here."""

        def __init__(self, n_in: int, n_out: int, kernel: int):
            super().__init__()
            self.kernel = kernel
            self.offset = nn.Conv1d(n_in, kernel, kernel, padding=kernel // 2)
            nn.init.zeros_(self.offset.weight)
            nn.init.zeros_(self.offset.bias)
            self.weight = nn.Parameter(torch.empty(n_out, n_in, kernel))
            self.bias = nn.Parameter(torch.zeros(n_out))
            nn.init.kaiming_uniform_(self.weight, a=math.sqrt(5))

        def forward(self, x):  # x: (batch, time, channels)
            xc = x.transpose(1, 2)  # (B, C, L)
            b, c, length = xc.shape
            delta = self.offset(xc)[..., :length]  # (B, K, L)
            taps = torch.arange(self.kernel, device=x.device, dtype=x.dtype) - self.kernel // 2
            pos = torch.arange(length, device=x.device, dtype=x.dtype).view(1, 1, -1) + taps.view(1, -1, 1) + delta
            pos = pos.clamp(0, length - 1)
            lo = pos.floor().long().clamp(max=length - 1)
            hi = (lo + 1).clamp(max=length - 1)
            frac = (pos - lo.to(x.dtype)).unsqueeze(1)  # (B, 1, K, L)

            def gather(idx):  # (B, K, L) -> (B, C, K, L)
                flat = idx.reshape(b, 1, -1).expand(b, c, -1)
                return xc.gather(2, flat).view(b, c, self.kernel, length)

            sampled = gather(lo) * (1 - frac) + gather(hi) * frac
            out = torch.einsum("bckl,ock->bol", sampled, self.weight) + self.bias.view(1, -1, 1)
            return out.transpose(1, 2)

    class FourierKAN(nn.Module):
        """Fourier Kolmogorov-Arnold layer (Xu et al. 2024, FourierKAN): y_j = b_j + sum_i sum_g a_jig cos(g u_i)
        + b_jig sin(g u_i), u = pi tanh(x) so every input lies in one period. A few lines, no library ships it."""

        def __init__(self, n_in: int, n_out: int, grid: int):
            super().__init__()
            self.register_buffer("k", torch.arange(1, grid + 1, dtype=torch.float32))
            scale = 1.0 / math.sqrt(n_in * grid)
            self.coef = nn.Parameter(torch.randn(2, n_out, n_in, grid) * scale)
            self.bias = nn.Parameter(torch.zeros(n_out))

        def forward(self, x):
            u = math.pi * torch.tanh(x).unsqueeze(-1) * self.k  # (B, in, grid)
            return (torch.einsum("big,oig->bo", torch.cos(u), self.coef[0])
                    + torch.einsum("big,oig->bo", torch.sin(u), self.coef[1]) + self.bias)

    class TemporalBlock(nn.Module):
        """TCN residual block (Bai, Kolter & Koltun 2018): two dilated causal convolutions, ReLU, dropout."""

        def __init__(self, n_in: int, n_out: int, kernel: int, dilation: int, dropout: float):
            super().__init__()
            self.net = nn.Sequential(Conv(n_in, n_out, kernel, dilation, causal=True), nn.ReLU(), nn.Dropout(dropout),
                                     Conv(n_out, n_out, kernel, dilation, causal=True), nn.ReLU(),
                                     nn.Dropout(dropout))
            self.skip = nn.Linear(n_in, n_out) if n_in != n_out else nn.Identity()

        def forward(self, x):
            return torch.relu(self.net(x) + self.skip(x))

    class ChannelAttention(nn.Module):
        """Squeeze-and-excitation over channels (Hu et al. 2018) on (batch, time, channels)."""

        def __init__(self, channels: int, reduction: int = 4):
            super().__init__()
            mid = max(1, channels // reduction)
            self.gate = nn.Sequential(nn.Linear(channels, mid), nn.ReLU(), nn.Linear(mid, channels), nn.Sigmoid())

        def forward(self, x):
            return x * self.gate(x.mean(dim=1)).unsqueeze(1)

    class TemporalAttention(nn.Module):
        """Softmax attention over time steps, pooling (batch, time, channels) to (batch, channels)."""

        def __init__(self, channels: int):
            super().__init__()
            self.score = nn.Linear(channels, 1)

        def forward(self, x):
            w = torch.softmax(self.score(x), dim=1)
            return (w * x).sum(dim=1)

    def encoder(width: int, heads: int, dropout: float) -> nn.Module:
        """One Transformer encoder layer (pre-norm, feed-forward 2 x width) on (batch, time, width)."""
        return nn.TransformerEncoderLayer(width, heads, dim_feedforward=2 * width, dropout=dropout, batch_first=True,
                                          norm_first=True)

    return dict(LastStep=LastStep, LSTMSequence=LSTMSequence, Conv=Conv, DeformableConv1d=DeformableConv1d,
                FourierKAN=FourierKAN, TemporalBlock=TemporalBlock, ChannelAttention=ChannelAttention,
                TemporalAttention=TemporalAttention, encoder=encoder)
