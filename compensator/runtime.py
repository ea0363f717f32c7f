"""From a model's exported state to its runtime: one module per family, imported only when a package needs it.

A runtime has ``inputs`` (column names in the order ``update`` reads them), ``targets`` and
``streamer(history=None, times_s=None)``, which returns an object whose ``update(values, t_s)`` takes one row
(a float array in ``inputs`` order; time in s) and returns the displacement per target (µm). ``history``: the
input rows before the first update (rows × inputs), ``times_s`` their times. Without limits the streamed values
equal the training side's ``model.predict(X, history)`` (to 1e-9 µm; float32 networks 1e-4 µm).
"""

from __future__ import annotations

import importlib
from typing import Any

# runtime name -> module holding its ``Runtime`` class (numpy only unless the family needs more)
MODULES = {
    "linear": "thermodrift.compensator.linear",
    "transfer_function": "thermodrift.compensator.filters",
    "lptn": "thermodrift.compensator.physics",
    "sequence": "thermodrift.compensator.networks",
    "pipeline": "thermodrift.compensator.pipeline",
    "ensemble": "thermodrift.compensator.pipeline",
}


def build(state: dict[str, Any]):
    """The runtime of an exported model ``state`` (``state["runtime"]`` names its family)."""
    name = state.get("runtime")
    if name not in MODULES:
        raise ValueError(f"unknown runtime {name!r}; this version knows {', '.join(sorted(MODULES))}")
    module = importlib.import_module(MODULES[name])
    return module.Runtime(state) if name != "ensemble" else module.Ensemble(state)


class Base:
    """Shared surface: the names a package states for every runtime."""

    def __init__(self, state: dict[str, Any]):
        self.state = state
        self.inputs = [str(c) for c in state["inputs"]]
        self.targets = [str(t) for t in state["targets"]]
        self.history_length = state.get("history_length", 0)

    def warm(self, streamer, history, times_s):
        """Run ``streamer`` through ``history`` rows (their outputs discarded); returns it."""
        if history is not None:
            rows = list(history)
            times = list(times_s) if times_s is not None else [None] * len(rows)
            for row, t in zip(rows, times):
                streamer.update(row, t)
        return streamer
