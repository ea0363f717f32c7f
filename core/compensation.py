"""Compensation as study S1 did it: origin translation per condition, and the CNC temperature-compensation table.

Origin translation shifts the work-coordinate origin by the predicted thermal error, so the error that remains
is the residual e = y − ŷ (µm). :func:`origin_translation` reports, per working or ambient condition, the error
before (max |y|, range of y) and after (range of e, max |e|) and the improvement 100 · (1 − max|e| / max|y|) %
(S1: 52/57/67 µm → 4–12/6–11/5–9 µm, 86/88/86 % on its three ambient conditions).

A CNC applies a temperature-compensation table per axis: ΔK(P) = K0(T) + tan β(T) · (P − P0), the offset K0 at
the reference position P0 and the slope along the axis, both functions of the machine's thermal state T.
:func:`cnc_table` builds it from a trained model's predictions at two or more positions along an axis (one
displacement channel per position): per row a least-squares line through the predicted errors over position.
``thermodrift compensate`` writes the same line per update in a controller's own units
(:mod:`thermodrift.compensator.cnc`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from thermodrift.compensator.cnc import axis_line

CNC_NOTE = ("# CNC temperature-compensation table. Per row (thermal state, indexed by the key temperature "
            "in degC and the time in s): offset K0_um at the reference position P0 and slope tan_beta_um_per_mm "
            "along the axis. The controller adds dK = K0(T) + tan_beta(T) * (P - P0) (um; P and P0 in mm) to the "
            "axis command, i.e. shifts the work origin by the predicted thermal error, interpolating between rows "
            "by the key temperature.\n")


def origin_translation(y_true: pd.DataFrame, y_pred: np.ndarray, conditions: pd.Series) -> pd.DataFrame:
    """Error before and after origin translation per condition and displacement channel (µm, %)."""
    pred = np.asarray(y_pred, dtype=float).reshape(len(y_true), -1)
    labels = np.asarray(conditions)
    rows = []
    for label in dict.fromkeys(labels):
        mask = labels == label
        for i, channel in enumerate(y_true.columns):
            y = y_true[channel].to_numpy(dtype=float)[mask]
            e = y - pred[mask, i]
            peak = float(np.abs(y).max())
            rows.append({"condition": label, "channel": channel, "samples": int(mask.sum()),
                         "error max µm": peak, "error range µm": f"{y.min():.1f} to {y.max():.1f}",
                         "compensated range µm": f"{e.min():.1f} to {e.max():.1f}",
                         "compensated max µm": float(np.abs(e).max()),
                         "improvement %": 100.0 * (1.0 - float(np.abs(e).max()) / peak) if peak > 0 else np.nan})
    return pd.DataFrame(rows)


def cnc_table(y_pred: np.ndarray, positions_mm: list[float], reference_mm: float, key_temperature: pd.Series,
              axis: str) -> pd.DataFrame:
    """K0 (µm) and tan β (µm/mm) per row from predictions (n, k) at ``positions_mm`` (k ≥ 1) along ``axis``.

    With one position the slope is undefined (NaN) and K0 is the prediction itself.
    """
    pred = np.asarray(y_pred, dtype=float).reshape(len(key_temperature), -1)
    k0, slope = axis_line(pred, positions_mm, reference_mm)  # the one line fit, shared with the compensator
    return pd.DataFrame({"time_s": np.asarray(key_temperature.index, dtype=float),
                         f"{key_temperature.name}_degC": key_temperature.to_numpy(dtype=float),
                         "axis": axis, "P0_mm": reference_mm, "K0_um": k0, "tan_beta_um_per_mm": slope})


def write_cnc_table(table: pd.DataFrame, path: str | Path) -> Path:
    """Write ``table`` as CSV with the note on how a controller applies it as leading comment lines."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", encoding="utf-8") as fh:
        fh.write(CNC_NOTE)
        table.to_csv(fh, index=False, float_format="%.4f")
    return path


def s1_ambient_evaluation(model: str = "transfer_function", selector: str = "fuzzy_sensitivity", seed: int = 0,
                          model_params: dict | None = None, selector_params: dict | None = None):
    """S1's compensation on turning_centre_s1: for each of the three ambient sessions, train on the other
    sessions (untuned defaults), compensate the held-out one by origin translation. Returns (table, results)."""
    from thermodrift.core import registry
    from thermodrift.core.study import Job, JobSpec

    rec = registry.create("dataset", "turning_centre_s1", seed=seed)
    tables, results = [], {}
    for condition in ("ambient_20C", "warm_ventilation", "ambient_17_27C"):
        spec = JobSpec(dataset="turning_centre_s1", model=model, selector=selector, n_trials=0, seed=seed,
                       model_params=dict(model_params or {}), selector_params=dict(selector_params or {}),
                       split="condition_holdout", split_params={"test_conditions": [condition], "train_on": "others"},
                       baselines=(), storage=None, progress=False)
        fold = Job(spec).run(recording=rec).folds[0]
        rows = np.searchsorted(rec.time_s, fold.time_s)
        duty = rec.conditions().iloc[rows].to_numpy()
        tables.append(origin_translation(fold.y_true, fold.predictions["model"], pd.Series(duty)))
        results[condition] = fold
    return pd.concat(tables, ignore_index=True), results
