"""Error metrics for displacement channels, all in µm (or µm² for MSE, or dimensionless where stated).

``compensation_rate`` = 1 − max|residual| / max|measured|: the share of the peak thermal error that a
compensation with this model would remove. ``relative_error_pct`` = 100 · mean|e| / mean|y|. ``mae`` is mean|e|;
``mean_error`` is the signed bias.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

NAMES = ("rmse", "mse", "mae", "max_abs_error", "mean_error", "r2", "explained_variance", "vaf",
         "relative_error_pct", "compensation_rate")


def rms(x, axis: int | None = None):
    """Root mean square of ``x`` (in its own unit) over ``axis`` (None: all values; a float then)."""
    return np.sqrt(np.mean(np.asarray(x) ** 2, axis=axis))


def rmse(y_true, y_pred, axis: int | None = None):
    """Root mean square error of ``y_pred`` against ``y_true`` (same unit, µm for displacements) over ``axis``."""
    return rms(np.asarray(y_true) - np.asarray(y_pred), axis=axis)


def channel_metrics(y_true_um: np.ndarray, y_pred_um: np.ndarray) -> dict[str, float]:
    """All metrics of one displacement channel (1-D arrays in µm), on the rows where it was measured (a sparse
    drift is NaN between measurements)."""
    y = np.asarray(y_true_um, dtype=float).ravel()
    p = np.asarray(y_pred_um, dtype=float).ravel()
    if y.shape != p.shape or y.size == 0:
        raise ValueError(f"need equal, non-empty shapes, got {y.shape} and {p.shape}")
    measured = ~np.isnan(y)
    if not measured.all():
        if not measured.any():
            raise ValueError("the channel is not measured in any of the rows scored")
        y, p = y[measured], p[measured]
    e = y - p
    abs_e = np.abs(e)
    var_y = float(np.var(y))
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    mean_abs_y = float(np.mean(np.abs(y)))
    max_abs_y = float(np.max(np.abs(y)))
    ev = 1.0 - float(np.var(e)) / var_y if var_y > 0 else float("nan")
    return {
        "rmse": float(rms(e)),
        "mse": float(np.mean(e ** 2)),
        "mae": float(np.mean(abs_e)),
        "max_abs_error": float(abs_e.max()),
        "mean_error": float(np.mean(e)),  # signed mean residual (bias), µm
        "r2": 1.0 - float(np.sum(e ** 2)) / ss_tot if ss_tot > 0 else float("nan"),
        "explained_variance": ev,
        "vaf": 100.0 * ev,
        "relative_error_pct": 100.0 * float(np.mean(abs_e)) / mean_abs_y if mean_abs_y > 0 else float("nan"),
        "compensation_rate": 1.0 - float(abs_e.max()) / max_abs_y if max_abs_y > 0 else float("nan"),
    }


def evaluate(y_true_um: pd.DataFrame, y_pred_um: np.ndarray) -> dict[str, dict[str, float]]:
    """Metrics per displacement channel plus ``"mean"`` over channels: ``{channel: {metric: value}}``."""
    pred = np.asarray(y_pred_um, dtype=float).reshape(len(y_true_um), -1)
    per = {col: channel_metrics(y_true_um[col].to_numpy(), pred[:, i]) for i, col in enumerate(y_true_um.columns)}
    per["mean"] = {name: float(np.mean([m[name] for m in per.values()])) for name in NAMES}
    return per
