"""What a training run leaves for ``thermodrift export``, logged beside its ``model`` artifact.

- ``limits.json``: per input the minimum, maximum, largest step per sample and longest constant run on the
  refit's training rows; per target the same in µm; the sampling interval (s); the targets' axes and positions
  from the manifest (:func:`thermodrift.compensator.limits.training_limits`).
- ``fallbacks/``: for families whose refit is cheap (linear and filter read-outs, pipelines around them and
  ensembles of such pipelines),
  one model per input fitted on the same training rows without that input, with the refit's parameters, as
  exported states (a compensator package tree: data only). A controller switches to one when that sensor fails
  (:mod:`thermodrift.compensator.guard`). Physics and network families get none: their refit costs minutes,
  and the compensator holds the last good value instead.

The training rows are those of the job's last fold (the refit's), as the job recorded them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd
from sklearn.base import clone

from thermodrift.compensator import limits as limits_mod

LIMITS = "limits.json"
FALLBACKS = "fallbacks"
FILTER_SETTLE = 5.0  # a filter's state is settled after this many of its longest time constants


def training_frame(result) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(inputs, targets) of the refit's training rows: the model's input columns with their roles in
    ``attrs["roles"]``, and the displacement targets (µm)."""
    rec, model, rows = result.recording, result.model, result.folds[-1].train_rows
    columns = [str(c) for c in model.feature_names_in_]
    X = rec.data[columns].iloc[rows]
    X.attrs["roles"] = {c: rec.channels[c].role for c in columns if c in rec.channels}
    return X, rec.data[result.targets].iloc[rows]


def axes(result) -> dict[str, dict[str, Any]]:
    """Per target the manifest's ``axis`` and ``position_mm`` (where given); ``unit: degC`` for a temperature
    target (a displacement target's unit, µm, is the default and not written)."""
    rec = result.recording
    out = {t: {k: v for k, v in rec.channels[t].meta.items() if k in ("axis", "position_mm", "location")}
           for t in result.targets if t in rec.channels}
    for t in out:
        if rec.channels[t].role == "temperature":
            out[t]["unit"] = rec.channels[t].unit
    return out


def limits(result) -> dict[str, Any]:
    """The ``limits.json`` content of a job result (see the module docstring)."""
    X, y = training_frame(result)
    return training_limits(X, y, axes(result))


def training_limits(X: pd.DataFrame, y: pd.DataFrame, target_axes: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """``limits.json`` of training inputs ``X`` (indexed by time in s) and targets ``y`` (µm)."""
    out = limits_mod.training_limits(X.to_numpy(dtype=float), list(X.columns), y.to_numpy(dtype=float),
                                     list(y.columns), np.asarray(X.index, dtype=float))
    out["axes"] = target_axes
    return out


def warmup_rows(state: dict[str, Any], sampling_interval_s: float) -> int:
    """Rows a fresh streamer of ``state`` needs before its output no longer depends on how it started."""
    if state.get("history_length") is not None:
        return int(state["history_length"])
    if state.get("runtime") == "ensemble":
        return max(warmup_rows(m, sampling_interval_s) for m in state["members"])
    if state.get("runtime") == "pipeline" and state.get("features") is None:
        return warmup_rows(state["model"], sampling_interval_s)
    taus = np.asarray((state.get("features") or {}).get("taus_s", []), dtype=float)
    longest = float(taus.max()) if len(taus) else 4 * 3600.0
    return int(math.ceil(FILTER_SETTLE * longest / sampling_interval_s))


def fallbacks(model, X: pd.DataFrame, y: pd.DataFrame, sampling_interval_s: float) -> dict[str, dict[str, Any]]:
    """Sensor -> {"state", "warmup_rows"}: the model refitted without each input, for models that declare they
    refit cheaply (``refits_cheaply``; a pipeline or an ensemble as the models inside it)."""
    if not getattr(model, "refits_cheaply", False) or X.shape[1] < 2:
        return {}
    try:
        model.export_state()
    except NotImplementedError:
        return {}
    out = {}
    for column in X.columns:
        rest = X.drop(columns=[column])
        rest.attrs = {"roles": {c: r for c, r in X.attrs.get("roles", {}).items() if c != column}}
        fitted = clone(model).fit(rest, y)
        fb = fitted.export_state()
        out[str(column)] = {"state": fb, "warmup_rows": warmup_rows(fb, sampling_interval_s)}
    return out


def not_exportable(result) -> str | None:
    """Why no controller can feed the job's model (it reads more than recorded channels, as the persistence
    reference reads the previous measured displacement), or None."""
    missing = [str(c) for c in result.model.feature_names_in_ if c not in result.recording.data.columns]
    if missing:
        return f"not exportable: inputs {', '.join(missing)[:200]} are not recorded channels"
    return None


def export_parts(result) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """The ``limits.json`` content and the ``fallbacks/`` of a job result (see the module docstring), which
    :func:`thermodrift.core.tracking.log_result` logs beside its ``model``."""
    X, y = training_frame(result)
    lim = training_limits(X, y, axes(result))
    return lim, fallbacks(result.model, X, y, lim["sampling_interval_s"])
