"""The compensator runtime: a trained pipeline as a controller runs it, from a data-only package.

This package is the lowest layer of thermodrift: it imports numpy (scipy for physics families, torch only for
networks) and nothing of ``thermodrift.core``, MLflow or Optuna, so a controller-side PC needs none of the
training stack. Training code may import from it, so the streaming arithmetic has one home.

``load(DIR)`` reads a package that ``thermodrift export`` wrote and returns a :class:`Package`:
``package.streamer()`` predicts one row at a time (µm per target) and ``package.compensator()`` wraps it with
input checks, fallbacks, rate limit, clamp and probe bias (:mod:`.guard`). :mod:`.stream` runs a table or a
live feed through it into a controller format (:mod:`.cnc`). Whatever a package, an option or a file holds that
the compensator cannot trust is refused before the first row with one :class:`InputError`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from thermodrift.compensator.errors import InputError, PackageError

__all__ = ["InputError", "Package", "PackageError", "load"]


class Package:
    """A loaded compensator package. ``inputs``: the columns a row holds, in order (names as in training;
    canonical units: °C, rpm, W); ``targets``: displacement channels (µm) with ``axes``; ``limits``: training
    ranges; ``safety``: the limits applied by default; ``fallbacks``: sensor -> model fitted without it.

    Every entry the compensator reads is checked here (:class:`PackageError` naming it), and the model and each
    fallback take one trial step, so a damaged package fails before the first row, never in the middle."""

    def __init__(self, doc: dict[str, Any], folder: Path | None = None):
        from thermodrift.compensator import runtime

        self.doc, self.folder = doc, folder
        where = str(folder) if folder is not None else "package"
        model = _entry(doc, "model", dict, where)
        self.model_state = model
        self.runtime = _built(lambda: runtime.build(model), "model", where)
        self.inputs: list[str] = list(self.runtime.inputs)
        self.targets: list[str] = list(self.runtime.targets)
        if not self.inputs or not self.targets:
            raise PackageError("the model reads no input or predicts no target", file=where,
                               hint="export the run again")
        self.axes: dict[str, dict[str, Any]] = _entry(doc, "axes", dict, where, {})
        self.limits: dict[str, Any] = _entry(doc, "limits", dict, where)
        self.safety: dict[str, Any] = _entry(doc, "safety", dict, where)
        self.sampling_interval_s = _positive(doc.get("sampling_interval_s"), "sampling_interval_s", where)
        self.fallbacks: dict[str, dict[str, Any]] = _entry(doc, "fallbacks", dict, where, {})
        self.probe: dict[str, float] = _entry(doc, "probe", dict, where, {})
        self.versions: dict[str, str] = _entry(doc, "versions", dict, where, {})
        self._check(where)

    def _check(self, where: str) -> None:
        """The numbers the guard reads, per input and target; one trial step of the model and each fallback."""
        for c in self.inputs:
            lim = _entry(_entry(self.limits, "inputs", dict, where, name="limits.inputs"), c, dict, where,
                         name=f"limits.inputs.{c}")
            low, high = (_number(lim.get(k), f"limits.inputs.{c}.{k}", where) for k in ("min", "max"))
            if not low <= high:
                raise PackageError(f"entry limits.inputs.{c}: min {low} above max {high}", file=where,
                                   hint="export the run again")
            for key in ("input_low", "input_high", "jump", "stuck_samples"):
                table = _entry(self.safety, key, dict, where, name=f"safety.{key}")
                _number(table.get(c), f"safety.{key}.{c}", where, infinite=key == "jump")
        for t in self.targets:
            for key in ("max_step_um", "clamp_um"):
                _positive(_entry(self.safety, key, dict, where, name=f"safety.{key}").get(t), f"safety.{key}.{t}",
                          where)
        _positive(self.safety.get("time_gap_factor"), "safety.time_gap_factor", where)
        for key in ("noise_um", "drift_um_per_sqrt_h", "initial_um"):
            if key in self.probe:
                _positive(self.probe[key], f"probe.{key}", where)
        if set(self.probe) - {"noise_um", "drift_um_per_sqrt_h", "initial_um"}:
            raise PackageError(f"entry probe names {sorted(self.probe)}", file=where, hint="export the run again")
        mid = [(self.limits["inputs"][c]["min"] + self.limits["inputs"][c]["max"]) / 2 for c in self.inputs]
        _trial(self.runtime, mid, len(self.targets), "model", where)
        from thermodrift.compensator import runtime

        for sensor, spec in self.fallbacks.items():
            name = f"fallbacks.{sensor}"
            if sensor not in self.inputs or not isinstance(spec, dict):
                raise PackageError(f"entry {name} is not a fallback for an input", file=where,
                                   hint="export the run again")
            warm = spec.get("warmup_rows", 0)
            if not isinstance(warm, int) or isinstance(warm, bool) or not 0 <= warm <= 1_000_000:
                raise PackageError(f"entry {name}.warmup_rows is not a row count", file=where,
                                   hint="export the run again")
            rt = _built(lambda: runtime.build(_entry(spec, "state", dict, where, name=f"{name}.state")), name, where)
            if not set(rt.inputs) <= set(self.inputs) or list(rt.targets) != self.targets:
                raise PackageError(f"entry {name} reads or predicts other channels than the model", file=where,
                                   hint="export the run again")
            _trial(rt, [mid[self.inputs.index(c)] for c in rt.inputs], len(self.targets), name, where)

    def streamer(self, history=None, times_s=None):
        """The model alone, one row per ``update(values, t_s)`` (no checks or limits)."""
        return self.runtime.streamer(history, times_s)

    def compensator(self, **options):
        """The model with input checks, fallbacks, limits and probe bias (:class:`~.guard.Compensator`)."""
        from thermodrift.compensator.guard import Compensator

        return Compensator(self, **options)


def load(folder: str | Path) -> Package:
    """The package in ``folder`` (written by ``thermodrift export``); :class:`PackageError` if it is not one."""
    from thermodrift.compensator import package as _package

    folder = Path(folder)
    return Package(_package.read(folder), folder)


_MISSING = object()
_JSON = {dict: "an object", list: "a list", str: "a string", int: "a number", float: "a number", bool: "a boolean",
         type(None): "null"}


def _entry(doc: Any, key: str, kind: type, where: str, default: Any = _MISSING, name: str | None = None) -> Any:
    """``doc[key]``, which must be a ``kind`` (a missing entry takes ``default`` where one is given)."""
    value = doc.get(key, default) if isinstance(doc, dict) else _MISSING
    if value is _MISSING or not isinstance(value, kind):
        what = "missing" if value is _MISSING else f"{_JSON.get(type(value), type(value).__name__)}, not " \
            f"{_JSON.get(kind, kind.__name__)}"
        raise PackageError(f"entry {name or key} is {what}", file=where,
                           hint="it was written by another version or changed; export the run again")
    return value


def _number(value: Any, name: str, where: str, infinite: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value) \
            or (math.isinf(value) and not infinite):
        raise PackageError(f"entry {name} is {value!r}, not a finite number", file=where,
                           hint="export the run again")
    return float(value)


def _positive(value: Any, name: str, where: str) -> float:
    number = _number(value, name, where)
    if number <= 0:
        raise PackageError(f"entry {name} is {number}, not positive", file=where, hint="export the run again")
    return number


def _built(make, name: str, where: str):
    """``make()``; whatever a damaged state makes a runtime raise becomes one :class:`PackageError`."""
    try:
        return make()
    except PackageError:
        raise
    except Exception as exc:  # a tampered state reaches any line of a runtime's constructor
        raise PackageError(f"entry {name} does not build ({type(exc).__name__}: {_short(exc)})", file=where,
                           hint="it was written by another version or changed; export the run again") from None


def _trial(rt, row: list[float], n_targets: int, name: str, where: str) -> None:
    """One update of a fresh streamer on the mid-range row: it must give one value per target."""
    import numpy as np

    def step():
        out = np.asarray(rt.streamer().update(np.asarray(row, dtype=float), 0.0), dtype=float)
        if out.shape != (n_targets,):
            raise ValueError(f"{out.shape[-1] if out.ndim else 1} values for {n_targets} targets")

    _built(step, name, where)


def _short(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:120]
