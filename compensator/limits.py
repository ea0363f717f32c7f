"""What the training data say is normal: per-input ranges and steps, per-target ranges, and the safety defaults
derived from them. Computed on the refit's training rows when a run is logged (``limits.json``) and stated in
the exported package, so every limit the compensator applies can be traced to data.
"""

from __future__ import annotations

from typing import Any

import numpy as np

# Safety defaults, as multiples of what the training data showed (stated in every package's "safety" section).
CLAMP_FACTOR = 1.5       # |written| <= CLAMP_FACTOR · max |training displacement| (µm)
STEP_FACTOR = 2.0        # |change per update| <= STEP_FACTOR · largest training step per sample (µm)
RANGE_MARGIN = 0.5       # an input outside [min − m, max + m], m = RANGE_MARGIN · (max − min), is a fault
JUMP_FACTOR = 5.0        # a change per sample above JUMP_FACTOR · the largest training step is a fault
STUCK_FACTOR = 2.0       # unchanged for more than STUCK_FACTOR · the longest training run (samples) is a fault
STUCK_MIN_SAMPLES = 20   # ... and never fewer samples than this


def _steps(values: np.ndarray, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|Δ| between consecutive rows one sampling interval apart (gaps between training blocks left out), and
    which pairs those are."""
    t = np.asarray(time_s, dtype=float)
    dt = np.diff(t)
    interval = float(np.median(dt)) if len(dt) else 1.0
    adjacent = dt <= 1.5 * interval
    return np.abs(np.diff(values, axis=0))[adjacent], adjacent


def _longest_constant(column: np.ndarray, adjacent: np.ndarray) -> int:
    same = (np.diff(column) == 0) & adjacent
    best = run = 0
    for s in same:
        run = run + 1 if s else 0
        best = max(best, run)
    return best + 1 if len(column) else 0


def training_limits(X: np.ndarray, columns: list[str], y: np.ndarray, targets: list[str],
                    time_s: np.ndarray) -> dict[str, Any]:
    """``{"sampling_interval_s", "inputs": {column: {min, max, max_step, longest_constant_samples}},
    "targets": {target: {min, max, max_step}}}`` of training rows ``X`` (°C, rpm, …) and ``y`` (µm)."""
    X = np.asarray(X, dtype=float).reshape(len(time_s), -1)
    y = np.asarray(y, dtype=float).reshape(len(time_s), -1)
    sx, adjacent = _steps(X, time_s)
    sy, _ = _steps(y, time_s)
    dt = np.diff(np.asarray(time_s, dtype=float))
    out: dict[str, Any] = {"sampling_interval_s": float(np.median(dt)) if len(dt) else 1.0, "inputs": {},
                           "targets": {}}
    for j, c in enumerate(columns):
        out["inputs"][str(c)] = {"min": float(np.nanmin(X[:, j])), "max": float(np.nanmax(X[:, j])),
                                 "max_step": float(sx[:, j].max()) if len(sx) else 0.0,
                                 "longest_constant_samples": _longest_constant(X[:, j], adjacent)}
    for j, t in enumerate(targets):
        out["targets"][str(t)] = {"min": float(np.nanmin(y[:, j])), "max": float(np.nanmax(y[:, j])),
                                  "max_step": float(sy[:, j].max()) if len(sy) else 0.0}
    return out


def safety_defaults(limits: dict[str, Any]) -> dict[str, Any]:
    """Rate limit and clamp per target (µm) and the input-check thresholds, from :func:`training_limits`."""
    targets = limits["targets"]
    inputs = limits["inputs"]
    return {
        "max_step_um": {t: STEP_FACTOR * v["max_step"] for t, v in targets.items()},
        "clamp_um": {t: CLAMP_FACTOR * max(abs(v["min"]), abs(v["max"])) for t, v in targets.items()},
        "input_low": {c: v["min"] - RANGE_MARGIN * (v["max"] - v["min"]) for c, v in inputs.items()},
        "input_high": {c: v["max"] + RANGE_MARGIN * (v["max"] - v["min"]) for c, v in inputs.items()},
        "jump": {c: JUMP_FACTOR * v["max_step"] if v["max_step"] > 0 else np.inf for c, v in inputs.items()},
        "stuck_samples": {c: max(STUCK_MIN_SAMPLES, int(np.ceil(STUCK_FACTOR * v["longest_constant_samples"])))
                          for c, v in inputs.items()},
        "time_gap_factor": 1.5,
        "rules": {"clamp_factor": CLAMP_FACTOR, "step_factor": STEP_FACTOR, "range_margin": RANGE_MARGIN,
                  "jump_factor": JUMP_FACTOR, "stuck_factor": STUCK_FACTOR, "stuck_min_samples": STUCK_MIN_SAMPLES},
    }
