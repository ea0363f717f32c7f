"""Runtime ``sequence``: windowed torch networks (``lstm``) from their weights, loaded with ``weights_only``.

A prediction reads the last ``window`` input rows (the first row repeated before the start, as in training),
Z-scored with the training scalers, through the network in float32; the output is scaled back to µm. The
architecture is rebuilt here from its name and sizes, so no code travels in the package.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import torch
from torch import nn

from thermodrift.compensator.runtime import Base


class _LSTM(nn.Module):
    """One LSTM layer and a linear head on the last step (the ``lstm`` model's network)."""

    def __init__(self, n_inputs: int, hidden: int, n_outputs: int):
        super().__init__()
        self.lstm = nn.LSTM(n_inputs, hidden, batch_first=True)
        self.head = nn.Linear(hidden, n_outputs)

    def forward(self, x):
        out, _ = self.lstm(x)
        return self.head(out[:, -1])


ARCHITECTURES = {"lstm": lambda s: _LSTM(int(s["n_inputs"]), int(s["hidden_units"]), int(s["n_outputs"]))}


class Runtime(Base):
    """State: ``architecture`` (a name in :data:`ARCHITECTURES`) and its sizes, ``window``, ``weights`` (a state
    dict of tensors), scalers ``x_mean``, ``x_scale``, ``y_mean``, ``y_scale``."""

    def __init__(self, state):
        super().__init__(state)
        arch = state.get("architecture")
        if arch not in ARCHITECTURES:
            raise ValueError(f"unknown network architecture {arch!r}; known: {', '.join(ARCHITECTURES)}")
        self.window = int(state["window"])
        self.net = ARCHITECTURES[arch](state)
        self.net.load_state_dict(state["weights"])
        self.net.eval()
        self.x_mean, self.x_scale = np.asarray(state["x_mean"], float), np.asarray(state["x_scale"], float)
        self.y_mean, self.y_scale = np.asarray(state["y_mean"], float), np.asarray(state["y_scale"], float)

    def streamer(self, history=None, times_s=None) -> "Streamer":
        s = Streamer(self)
        if history is not None and len(history):
            for row in np.asarray(history, dtype=float)[-(self.window - 1):] if self.window > 1 else []:
                s.push(row)
        return s


class Streamer:
    def __init__(self, rt: Runtime):
        self.rt = rt
        self.rows: deque = deque(maxlen=rt.window)

    def push(self, values: np.ndarray) -> None:
        z = (np.asarray(values, dtype=float) - self.rt.x_mean) / self.rt.x_scale
        if not self.rows:  # edge padding: the first row stands for the rows before it
            self.rows.extend([z] * (self.rt.window - 1))
        self.rows.append(z)

    def update(self, values: np.ndarray, t_s: float | None = None) -> np.ndarray:
        self.push(values)
        x = torch.as_tensor(np.asarray(self.rows)[None], dtype=torch.float32)
        with torch.no_grad():
            out = self.rt.net(x).numpy()[0]
        return out * self.rt.y_scale + self.rt.y_mean
