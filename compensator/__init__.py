"""The compensator runtime: a trained pipeline as a controller runs it, from a data-only package.

This package is the lowest layer of thermodrift: it imports numpy (scipy for physics families, torch only for
networks) and nothing of ``thermodrift.core``, MLflow or Optuna, so a controller-side PC needs none of the
training stack. Training code may import from it, so the streaming arithmetic has one home.

``load(DIR)`` reads a package that ``thermodrift export`` wrote and returns a :class:`Package`:
``package.streamer()`` predicts one row at a time (µm per target) and ``package.compensator()`` wraps it with
input checks, fallbacks, rate limit, clamp and probe bias (:mod:`.guard`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from thermodrift.compensator import package as _package
from thermodrift.compensator.package import PackageError

__all__ = ["Package", "PackageError", "load"]


class Package:
    """A loaded compensator package. ``inputs``: the columns a row holds, in order (names as in training;
    canonical units: °C, rpm, W); ``targets``: displacement channels (µm) with ``axes``; ``limits``: training
    ranges; ``safety``: the limits applied by default; ``fallbacks``: sensor -> model fitted without it."""

    def __init__(self, doc: dict[str, Any], folder: Path | None = None):
        from thermodrift.compensator import runtime

        self.doc, self.folder = doc, folder
        self.model_state = doc["model"]
        self.runtime = runtime.build(self.model_state)
        self.inputs: list[str] = list(self.runtime.inputs)
        self.targets: list[str] = list(self.runtime.targets)
        self.axes: dict[str, dict[str, Any]] = doc.get("axes", {})
        self.limits: dict[str, Any] = doc["limits"]
        self.safety: dict[str, Any] = doc["safety"]
        self.sampling_interval_s = float(doc["sampling_interval_s"])
        self.fallbacks: dict[str, dict[str, Any]] = doc.get("fallbacks", {})
        self.probe: dict[str, float] = doc.get("probe", {})
        self.versions: dict[str, str] = doc.get("versions", {})

    def streamer(self, history=None, times_s=None):
        """The model alone, one row per ``update(values, t_s)`` (no checks or limits)."""
        return self.runtime.streamer(history, times_s)

    def compensator(self, **options):
        """The model with input checks, fallbacks, limits and probe bias (:class:`~.guard.Compensator`)."""
        from thermodrift.compensator.guard import Compensator

        return Compensator(self, **options)


def load(folder: str | Path) -> Package:
    """The package in ``folder`` (written by ``thermodrift export``); :class:`PackageError` if it is not one."""
    folder = Path(folder)
    doc = _package.read(folder)
    try:
        return Package(doc, folder)
    except KeyError as missing:
        raise PackageError(f"{folder}: the package has no entry {missing}; it was written by another version, "
                           "export the run again") from None
