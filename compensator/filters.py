"""Runtime ``transfer_function``: the feature stage (raw and first-order-filtered temperatures and drive heat
terms, :mod:`thermodrift.compensator.features`) and a linear read-out W · features + c (µm)."""

from __future__ import annotations

import numpy as np

from thermodrift.compensator.features import FeatureStage
from thermodrift.compensator.runtime import Base


class Runtime(Base):
    """State: ``features`` (a feature-stage state), ``weights`` (targets × features), ``intercept`` (targets)."""

    def __init__(self, state):
        super().__init__(state)
        self.stage = FeatureStage.from_state(state["features"])
        pos = {c: i for i, c in enumerate(self.inputs)}
        self.idx = np.array([pos[c] for c in self.stage.inputs], dtype=int)
        self.weights = np.atleast_2d(np.asarray(state["weights"], dtype=float))
        self.intercept = np.asarray(state["intercept"], dtype=float).reshape(-1)

    def streamer(self, history=None, times_s=None) -> "Streamer":
        past = None if history is None or not len(history) else np.asarray(history, dtype=float)[:, self.idx]
        return Streamer(self, past)


class Streamer:
    def __init__(self, rt: Runtime, past):
        self.rt, self.stream = rt, rt.stage.stream(past)

    def update(self, values: np.ndarray, t_s: float | None = None) -> np.ndarray:
        return self.rt.weights @ self.stream.update(values[self.rt.idx]) + self.rt.intercept
