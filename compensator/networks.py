"""Runtime ``sequence``: torch networks from their weights, loaded with ``weights_only``.

A prediction reads the last ``window`` input rows (the first row repeated before the start, as in training;
one row for a memoryless network), Z-scored with the training scalers, through the network in float32; the
output is scaled back to µm. Two architectures:

- ``lstm``: rebuilt here from its sizes (the ``lstm`` model's network);
- ``torch.export``: any other network of a ``TorchThermalModel``, as the graph ``torch.export`` traced for one
  sample (JSON, the operators of ``torch.ops`` by name) and its weights. ``torch.export.load`` would fall back
  to unpickling (``weights_only=False``) when the safe load fails; here the weights come from the package's
  ``weights_only`` file and only the JSON graph is deserialised (torch's serde, pinned with torch).

No code travels in the package.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import torch
from torch import nn

from thermodrift.compensator.runtime import Base


class LSTMNet(nn.Module):
    """One LSTM layer and a linear head on the last step: the ``lstm`` model's network (it builds it from here)."""

    def __init__(self, n_inputs: int, hidden: int, n_outputs: int):
        super().__init__()
        self.lstm = nn.LSTM(n_inputs, hidden, batch_first=True)
        self.head = nn.Linear(hidden, n_outputs)

    def forward(self, x):
        out, _ = self.lstm(x)
        return self.head(out[:, -1])


def _exported(state) -> nn.Module:
    """The module of a ``torch.export`` graph (JSON bytes) with weights and constants given as tensors."""
    from torch._export.serde import serialize as serde

    params = set(state.get("parameters", []))
    weights = {k: nn.Parameter(v, requires_grad=False) if k in params else v for k, v in state["weights"].items()}
    window = state.get("window")
    shape = (1, len(state["x_mean"])) if window is None else (1, int(window), len(state["x_mean"]))
    artifact = serde.SerializedArtifact(np.asarray(state["program"], dtype=np.uint8).tobytes(),
                                        weights, dict(state.get("constants") or {}),
                                        ((torch.zeros(shape),), {}))
    return serde.deserialize(artifact).module()


ARCHITECTURES = {"lstm": lambda s: LSTMNet(int(s["n_inputs"]), int(s["hidden_units"]), int(s["n_outputs"])),
                 "torch.export": _exported}


class Runtime(Base):
    """State: ``architecture`` (a name in :data:`ARCHITECTURES`) and its sizes, ``window``, ``weights`` (a state
    dict of tensors), scalers ``x_mean``, ``x_scale``, ``y_mean``, ``y_scale``."""

    def __init__(self, state):
        super().__init__(state)
        arch = state.get("architecture")
        if arch not in ARCHITECTURES:
            raise ValueError(f"unknown network architecture {arch!r}; known: {', '.join(ARCHITECTURES)}")
        self.window = state["window"] if state["window"] is None else int(state["window"])
        self.net = ARCHITECTURES[arch](state)
        if arch == "lstm":
            self.net.load_state_dict(state["weights"])
            self.net.eval()
        self.x_mean, self.x_scale = np.asarray(state["x_mean"], float), np.asarray(state["x_scale"], float)
        self.y_mean, self.y_scale = np.asarray(state["y_mean"], float), np.asarray(state["y_scale"], float)

    def streamer(self, history=None, times_s=None) -> "Streamer":
        s = Streamer(self)
        if history is not None and len(history) and self.window and self.window > 1:
            for row in np.asarray(history, dtype=float)[-(self.window - 1):]:
                s.push(row)
        return s


class Streamer:
    def __init__(self, rt: Runtime):
        self.rt = rt
        self.rows: deque = deque(maxlen=rt.window or 1)

    def push(self, values: np.ndarray) -> None:
        z = (np.asarray(values, dtype=float) - self.rt.x_mean) / self.rt.x_scale
        if not self.rows and self.rt.window:  # edge padding: the first row stands for the rows before it
            self.rows.extend([z] * (self.rt.window - 1))
        self.rows.append(z)

    def update(self, values: np.ndarray, t_s: float | None = None) -> np.ndarray:
        self.push(values)
        batch = np.asarray(self.rows)[None] if self.rt.window else self.rows[-1][None]
        x = torch.as_tensor(batch, dtype=torch.float32)
        with torch.no_grad():
            out = self.rt.net(x).numpy()[0]
        return out * self.rt.y_scale + self.rt.y_mean
