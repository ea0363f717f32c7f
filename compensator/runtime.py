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


class Family:
    """A built-in runtime family: ``Family(module, cls)(state)`` imports ``module`` on first use (numpy only,
    scipy for physics, torch only for a network) and builds its runtime."""

    def __init__(self, module: str, cls: str, description: str):
        self.module, self.cls, self.description = module, cls, description

    def __call__(self, state: dict[str, Any]):
        return getattr(importlib.import_module(self.module), self.cls)(state)


_PKG = "thermodrift.compensator."


def thermodrift_register_runtimes(registry):
    """The built-in families (a third-party runtime registers its own class from its own module)."""
    for name, module, cls, text in (
            ("linear", "linear", "Runtime", "y = ((x − mean) / scale) · coef + intercept, as mlr predicts "
             "(µm from °C)."),
            ("transfer_function", "filters", "Runtime", "The feature stage (raw and first-order-filtered "
             "temperatures, drive heat terms) and a linear read-out (µm)."),
            ("lptn", "physics", "Runtime", "The calibrated thermal network's state observer and its linear "
             "read-out (lptn, lptn_hybrid)."),
            ("sequence", "networks", "Runtime", "Torch networks from their weights, loaded with weights_only."),
            ("pipeline", "pipeline", "Runtime", "The AutoML pipeline: selected raw inputs, feature stage, inner "
             "model."),
            ("ensemble", "pipeline", "Ensemble", "A weighted sum of pipelines (µm).")):
        registry.add("runtime", name, Family(_PKG + module, cls, text))


def build(state: dict[str, Any]):
    """The runtime of an exported model ``state`` (``state["runtime"]`` names its family, a registered runtime)."""
    from thermodrift.compensator import discovery

    name = state.get("runtime")
    factory = discovery.find("runtime", name) if isinstance(name, str) else None
    if factory is None:
        raise ValueError(f"unknown runtime {name!r}; installed: {', '.join(sorted(discovery.components('runtime')))}")
    return factory(state)


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
