"""CNC format ``fanuc``: thermal growth compensation (Series 15i/150i-MA Connection Manual (Function)
B-63323EN-1/03, §1 "thermal growth compensation along tool vector").

Absolute values in detection units (1 µm on IS-B metric machines; ``detection_unit_um``); "the amount of the
compensation, 9999 or more (−9999 or less) by using the detection unit, cannot be output once for an axis", so a
change of 9999 units or more is written as several rows of at most 9998 units each.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from thermodrift.compensator.cnc.base import Format, number
from thermodrift.compensator.guard import STATUSES, Step

MAX_UNITS = 9998  # the documented limit is a change below 9999 detection units per output


class Fanuc(Format):
    """Absolute compensation per target in detection units, changes split below 9999 units per output."""

    def header(self) -> list[str]:
        return ["time_s"] + [f"{t}_units" for t in self.targets] + [f"{t}_status" for t in self.targets]

    def rows(self, step: Step) -> list[list[Any]]:
        status = [STATUSES[s] for s in step.status]
        units = np.round(step.written / self.unit_um).astype(np.int64)
        prev = self.last.get("fanuc", units)
        self.last["fanuc"] = units
        n = max(1, int(math.ceil(np.max(np.abs(units - prev)) / MAX_UNITS))) if len(units) else 1
        return [[number(step.time_s)] + [int(v) for v in np.round(prev + (units - prev) * k / n).astype(np.int64)]
                + status for k in range(1, n + 1)]


def thermodrift_register_cnc_formats(registry):
    registry.add("cnc", "fanuc", Fanuc)
