"""The audit log: one JSON line per written row, so every value a controller received can be traced.

Each line holds the time (s), the inputs as received (canonical units; null for a missing value), the model's
raw prediction and the written value per target (µm), the status per target, the limits in force (rate limit
and clamp per target, µm), the probe bias (µm) when probes are used, what produced the value (``model``,
``fallback:<sensor>`` or ``hold``) and the reasons: every failed input as {"sensor", "reason"} (``missing``,
``out_of_range``, ``stuck``, ``jump``; ``time`` with ``time_not_increasing`` or ``time_gap``) and, per target,
the limit that changed the value.
"""

from __future__ import annotations

import json
from typing import IO

import numpy as np

from thermodrift.compensator.guard import CLAMPED, RATE_LIMITED, STATUSES, Step


def _f(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


class Audit:
    """Writes lines to an open text stream ``out``."""

    def __init__(self, out: IO[str], package, compensator):
        self.out, self.inputs, self.targets = out, package.inputs, package.targets
        self.max_step = {t: float(v) for t, v in zip(self.targets, compensator.max_step)}
        self.clamp = {t: float(v) for t, v in zip(self.targets, compensator.clamp)}
        self.limits_on = compensator.limits

    def write(self, step: Step, values: np.ndarray) -> None:
        reasons = [{"sensor": s, "reason": r} for s, r in step.faults]
        for t, s in zip(self.targets, step.status):
            if s in (RATE_LIMITED, CLAMPED):
                reasons.append({"target": t, "reason": STATUSES[s], "applied": self.limits_on})
        line = {"time_s": step.time_s, "inputs": {c: _f(v) for c, v in zip(self.inputs, values)},
                "raw_um": {t: _f(v) for t, v in zip(self.targets, step.raw)},
                "written_um": {t: _f(v) for t, v in zip(self.targets, step.written)},
                "status": {t: STATUSES[s] for t, s in zip(self.targets, step.status)},
                "source": step.source, "limits": {"max_step_um": self.max_step, "clamp_um": self.clamp,
                                                  "applied": self.limits_on},
                "reasons": reasons}
        if step.bias is not None:
            line["bias_um"] = {t: _f(v) for t, v in zip(self.targets, step.bias)}
        self.out.write(json.dumps(line) + "\n")
