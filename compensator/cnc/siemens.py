"""CNC format ``siemens``: SINUMERIK 840D sl temperature compensation (Function Manual Extended Functions, K3
Compensations, §4.2 Temperature compensation, 6FC5397-1BP40-3BA1, 03/2013).

Per axis the setting data SD43900 ``$SA_TEMP_COMP_ABS_VALUE`` (position-independent value K0, mm), SD43910
``$SA_TEMP_COMP_SLOPE`` (tan β of the position-dependent part, dimensionless: the manual writes
tan β(T) = … · 10⁻⁶ from a coefficient in µm/m) and SD43920 ``$SA_TEMP_COMP_REF_POSITION`` (P0, mm; the
manual's example sets 320 for 320 mm). The NC limits how fast the total compensation may change per
interpolation cycle to MD32760 ``$MA_COMP_ADD_VELO_FACTOR`` × MD32000 ``$MA_MAX_AX_VELO``; a larger change is
written as several rows one interpolation cycle apart, each within that limit over the axis's positions.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from thermodrift.compensator.cnc.base import Format, number
from thermodrift.compensator.guard import STATUSES, Step

COLUMNS = ("SD43900_TEMP_COMP_ABS_VALUE_mm", "SD43910_TEMP_COMP_SLOPE", "SD43920_TEMP_COMP_REF_POSITION_mm")


class Siemens(Format):
    """SD43900 K0 (mm), SD43910 tan β, SD43920 P0 (mm) per axis, within MD32760 × MD32000 per cycle."""

    def __init__(self, package, **settings: Any):
        super().__init__(package, **settings)
        # MD32760 × MD32000 per interpolation cycle (µm per cycle)
        self.step_um = self.velo_factor * self.max_axis_velo_mm_min / 60.0 * self.ipo_cycle_s * 1000.0

    def header(self) -> list[str]:
        return ["time_s"] + [f"{a.name}.{c}" for a in self.axes for c in COLUMNS] + [f"{a.name}_status"
                                                                                     for a in self.axes]

    def rows(self, step: Step) -> list[list[Any]]:
        """Rows one interpolation cycle apart so that the change at every position of every axis stays within
        the MD32760 limit."""
        now = np.array([self.line(a, step.written) for a in self.axes])  # (axes, 2): K0 µm, tan β µm/mm
        ax_status = [max((step.status[i] for i in a.targets)) for a in self.axes]
        prev = self.last.get("siemens", now)
        self.last["siemens"] = now
        worst = 0.0
        for a, (d0, ds) in zip(self.axes, now - prev):
            reach = np.abs(a.positions_mm - self.reference_mm).max() if len(a.targets) > 1 else 0.0
            worst = max(worst, abs(d0) + abs(ds) * reach)
        n = max(1, int(math.ceil(worst / self.step_um))) if worst > 0 else 1
        rows = []
        for k in range(1, n + 1):
            cur = prev + (now - prev) * k / n
            rows.append([number(step.time_s + (k - n) * self.ipo_cycle_s)]
                        + [v for k0, slope in cur for v in (number(k0 / 1000.0), number(slope / 1000.0),
                                                             number(self.reference_mm))]
                        + [STATUSES[s] for s in ax_status])
        return rows


def thermodrift_register_cnc_formats(registry):
    registry.add("cnc", "siemens", Siemens)
