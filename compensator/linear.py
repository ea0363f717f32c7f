"""Runtime ``linear``: y = ((x − mean) / scale) · coef + intercept, as ``mlr`` predicts (µm from °C)."""

from __future__ import annotations

import numpy as np

from thermodrift.compensator.runtime import Base


class Runtime(Base):
    """Memoryless: one dot product per row. State: ``mean``, ``scale`` (per input), ``coef`` (inputs × targets),
    ``intercept`` (targets)."""

    def __init__(self, state):
        super().__init__(state)
        self.mean = np.asarray(state["mean"], dtype=float)
        self.scale = np.asarray(state["scale"], dtype=float)
        self.coef = np.asarray(state["coef"], dtype=float).reshape(len(self.inputs), -1)
        self.intercept = np.asarray(state["intercept"], dtype=float).reshape(-1)

    def streamer(self, history=None, times_s=None) -> "Streamer":
        return Streamer(self)


class Streamer:
    def __init__(self, rt: Runtime):
        self.mean, self.scale, self.coef, self.intercept = rt.mean, rt.scale, rt.coef, rt.intercept

    def update(self, values: np.ndarray, t_s: float | None = None) -> np.ndarray:
        return ((values - self.mean) / self.scale) @ self.coef + self.intercept
