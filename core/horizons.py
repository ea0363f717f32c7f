"""Held-out scores at forecast horizons: how old the last measured target is when a prediction is made.

A model that reads only inputs (every family AutoML searches, every compensation model) predicts the same at every
horizon: it never sees the measured target, so its one-step and its 24 h ahead predictions are one simulation from
the inputs. A reference that reads the measured target (``uses_target_history``: persistence) sees it ``k``
samples old at a horizon of ``k`` samples: the previous sample at one step, the value a day before at 24 h.
:func:`scores` refits such references on each fold's training rows with their target history lagged by the
horizon and states every model's held-out RMSE per horizon, in the targets' unit (µm or K).

Horizons are given in hours (``horizons_h``); each is rounded to whole sampling intervals, at least one (so 0 asks
for the one-step prediction).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from thermodrift.core import registry
from thermodrift.core.errors import InputError
from thermodrift.core.metrics import evaluate
from thermodrift.core.study import input_columns, model_inputs, predict_rows


def steps(horizon_h: float, interval_s: float) -> int:
    """The horizon ``horizon_h`` (h) in whole sampling intervals of ``interval_s`` (s), at least one."""
    if not horizon_h >= 0:
        raise InputError(f"horizons_h: a horizon is 0 (one step) or more hours, got {horizon_h!r}",
                         hint="e.g. horizons_h=[0,24]")
    return max(1, int(round(horizon_h * 3600.0 / interval_s)))


def label(k: int, interval_s: float) -> str:
    """``one step (15 min)`` for one sampling interval, else the horizon in h (``24 h``)."""
    if k == 1:
        return f"one step ({interval_s / 60:g} min)" if interval_s >= 60 else f"one step ({interval_s:g} s)"
    return f"{k * interval_s / 3600:g} h"


def scores(result, horizons_h) -> pd.DataFrame:
    """Held-out RMSE (mean over targets and folds; µm or K) of the model and each baseline of the
    :class:`~thermodrift.core.study.JobResult` ``result``, one column per horizon of ``horizons_h`` (h)."""
    rec, spec = result.recording, result.spec
    interval = rec.sampling_interval_s
    lags = list(dict.fromkeys(steps(float(h), interval) for h in horizons_h))
    rows: dict[str, dict[str, float]] = {}
    for who in result.folds[0].predictions:
        name = spec.model if who == "model" else who
        cls = registry.get("model", name).factory
        reads_target = getattr(cls, "uses_target_history", False)
        row = {}
        for k in lags:
            rmse = []
            for fold in result.folds:
                test = np.searchsorted(rec.time_s, fold.time_s)
                pred = (_lagged(rec, fold, who, name, cls, result.targets, spec, k, test) if reads_target
                        else fold.predictions[who])
                rmse.append(evaluate(fold.y_true, pred)["mean"]["rmse"])
            row[label(k, interval)] = float(np.mean(rmse))
        rows[f"model: {name}" if who == "model" else who] = row
    return pd.DataFrame.from_dict(rows, orient="index")


def _lagged(rec, fold, who: str, name: str, cls, targets: list[str], spec, lag: int, test: np.ndarray) -> np.ndarray:
    """A target-reading reference refitted on the fold's training rows with its target history ``lag`` samples
    old, and its predictions of the held-out rows."""
    inputs = list(fold.selected) or input_columns(rec, spec.input_roles, targets)
    frame = model_inputs(rec, inputs, cls, targets, lag=lag)
    params = dict(fold.best_params) if who == "model" else {}
    model = registry.create("model", name, **params).fit(frame.iloc[fold.train_rows], rec.data[targets].iloc[fold.train_rows])
    return predict_rows(model, frame, test)
