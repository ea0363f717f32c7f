"""Adequacy first: the auto baseline's structure chosen on a held-out block, and how adequate the result is.

Before mechanisms compete to explain the residual, the structural misfit the baseline itself can shed is shed:
the ``auto`` network is calibrated on the screening rows before the inner validation block with each set of
hidden nodes in :data:`HIDDEN_OPTIONS` (unmeasured heat paths that act on the displacements only, each adding
a time constant to the expansion map) and the set that predicts the validation block best (noise-weighted,
temperature and displacement channels balanced) is kept; a larger set must beat a smaller one by
:data:`MIN_GAIN` of its held-out error. Links to the coolant or extra ambient paths are mechanisms the finder
tests (``coolant_coupling``, ``ambient_coupling``): adding them here would hide what it is asked to find. The
search happens in :func:`thermodrift.core.physics.diagnose.diagnose` only; the ``auto`` network that ``lptn``
and ``lptn_hybrid`` calibrate keeps its default.

:func:`assess` then says how adequate the chosen baseline is: its fitted drift error against the drift sensors'
noise, the correlation of its residual (the noise model's AR coefficient sum, :mod:`.noise`) and its error on
the inner validation block against its fitted error.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from thermodrift.core.physics.calibration import calibrate

# Hidden nodes by their start time constants (h): the auto network's default pair, one more with a fast path
# (minutes: heat that reaches the structure quicker than any surface sensor shows it) and a finer spread.
HIDDEN_OPTIONS = ((0.5, 4.0), (0.1, 0.7, 4.0), (0.1, 0.5, 1.5, 4.0))
MIN_GAIN = 0.05
STRUCTURAL_RATIO = 2.0  # fitted drift error over this many noise σ: misfit beyond noise (structural)


def _balanced_error(measured: np.ndarray, readings: np.ndarray, sigma: np.ndarray, kinds: list[str],
                    rows: np.ndarray) -> float:
    """Mean squared noise-weighted error on ``rows``, temperature and displacement channels weighing half each."""
    err = (((measured - readings) / sigma)[rows]) ** 2
    groups = [np.array([k == kind for k in kinds]) for kind in ("temperature", "displacement")]
    parts = [float(err[:, g].mean()) for g in groups if g.any()]
    return float(np.mean(parts))


def choose_hidden(recording, inner_rows: np.ndarray, val_rows: np.ndarray, scenario, evaluations: int,
                  baseline_of) -> tuple[tuple[float, ...], list[dict[str, Any]]]:
    """The hidden nodes (start time constants, h) of the auto baseline that predicts ``val_rows`` best when
    calibrated on ``inner_rows`` (indices into ``recording``), and the table of every set tried (held-out error
    in noise units). ``baseline_of`` is the screening's linear refit (:func:`.screening.baseline_of`)."""
    inner_rec = recording.select(np.isin(np.arange(len(recording)), inner_rows))
    table, best = [], None
    for h in HIDDEN_OPTIONS:
        cal = calibrate(inner_rec, None, hidden_nodes=h, intervals=False, max_evaluations=evaluations,
                        prior_strength=0.0)
        channels = list(cal.sigma)
        kinds = [cal.channel_kind[c] for c in channels]
        sigma = np.array([cal.sigma[c] for c in channels])
        measured = recording.data[channels].to_numpy(dtype=float)
        readings = baseline_of(cal.network, scenario, channels, measured, inner_rows, sigma).readings
        err = _balanced_error(measured, readings, sigma, kinds, val_rows)
        fit_err = _balanced_error(measured, readings, sigma, kinds, inner_rows)
        table.append({"hidden_nodes": len(h), "time_constants_h": list(h), "heldout_error": round(err, 4),
                      "fitted_error": round(fit_err, 4)})
        if best is None or err < (1 - MIN_GAIN) * best[1]:
            best = (h, err)
    for row in table:
        row["chosen"] = tuple(row["time_constants_h"]) == best[0]
    return best[0], table


def assess(channels: list[str], kinds: list[str], sigma: np.ndarray, measured: np.ndarray, readings: np.ndarray,
           rows: np.ndarray, val_rows: np.ndarray, val_readings: np.ndarray, noise) -> dict[str, Any]:
    """How adequate the baseline is, per displacement channel: fitted RMSE (µm) and its ratio to the noise σ,
    the inner validation block's RMSE (fitted without it) and its ratio to the fitted one, and the residual's
    AR coefficient sum; ``structural`` when some drift channel misses by over :data:`STRUCTURAL_RATIO` σ."""
    out: dict[str, Any] = {"channels": {}}
    ar = noise.describe(channels)
    for j, (c, k) in enumerate(zip(channels, kinds)):
        if k != "displacement":
            continue
        fit = float(np.sqrt(np.mean((measured[rows, j] - readings[rows, j]) ** 2)))
        val = float(np.sqrt(np.mean((measured[val_rows, j] - val_readings[val_rows, j]) ** 2))) if len(
            val_rows) else float("nan")
        out["channels"][c] = {"rmse_um": round(fit, 4), "noise_um": round(float(sigma[j]), 4),
                              "misfit_over_noise": round(fit / sigma[j], 2),
                              "validation_rmse_um": round(val, 4),
                              "validation_over_fitted": round(val / fit, 2) if fit > 0 else None,
                              "residual_ar_sum": ar[c]["phi_sum"]}
    out["structural"] = any(v["misfit_over_noise"] > STRUCTURAL_RATIO for v in out["channels"].values())
    return out
