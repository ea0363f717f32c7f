"""Runtimes ``pipeline`` and ``ensemble``: the AutoML pipeline (selected raw inputs → feature stage → inner model)
and a weighted sum of pipelines.

The feature stage's state is defined by :mod:`thermodrift.compensator.features` (``FeatureStage.from_state``,
``stage.stream(history)`` with ``update(values)``); the inner model is any runtime. History rows run through
both stages, so the inner model's state sees the features of the history, as the batch prediction does.
"""

from __future__ import annotations

import numpy as np

from thermodrift.compensator import runtime
from thermodrift.compensator.runtime import Base


class Runtime(Base):
    """State: ``selected`` (raw inputs the selector kept), ``features`` (a feature-stage state or None),
    ``model`` (the inner model's exported state)."""

    def __init__(self, state):
        super().__init__(state)
        pos = {c: i for i, c in enumerate(self.inputs)}
        self.sel_idx = np.array([pos[c] for c in state["selected"]], dtype=int)
        self.stage = None
        if state.get("features") is not None:
            from thermodrift.compensator.features import FeatureStage

            self.stage = FeatureStage.from_state(state["features"])
        self.model = runtime.build(state["model"])

    def streamer(self, history=None, times_s=None) -> "Streamer":
        return self.warm(Streamer(self), history, times_s)


class Streamer:
    def __init__(self, rt: Runtime):
        self.rt = rt
        self.features = rt.stage.stream(None) if rt.stage is not None else None
        self.model = rt.model.streamer()

    def update(self, values: np.ndarray, t_s: float | None = None) -> np.ndarray:
        x = values[self.rt.sel_idx]
        if self.features is not None:
            x = np.asarray(self.features.update(x), dtype=float)
        return self.model.update(x, t_s)


class Ensemble(Base):
    """State: ``weights`` (one per member) and ``members`` (pipeline states); output = Σ wᵢ · memberᵢ."""

    def __init__(self, state):
        super().__init__(state)
        pos = {c: i for i, c in enumerate(self.inputs)}
        self.members = [runtime.build(m) for m in state["members"]]
        self.idx = [np.array([pos[c] for c in m.inputs], dtype=int) for m in self.members]
        self.weights = np.asarray(state["weights"], dtype=float).reshape(-1)

    def streamer(self, history=None, times_s=None) -> "EnsembleStreamer":
        return self.warm(EnsembleStreamer(self), history, times_s)


class EnsembleStreamer:
    def __init__(self, rt: Ensemble):
        self.rt = rt
        self.members = [m.streamer() for m in rt.members]

    def update(self, values: np.ndarray, t_s: float | None = None) -> np.ndarray:
        outs = [s.update(values[i], t_s) for s, i in zip(self.members, self.rt.idx)]
        return np.tensordot(self.rt.weights, np.asarray(outs), axes=1)
