"""CNC format ``beckhoff``: TwinCAT CNC TF5200 axis compensation, temperature compensation (parameters
P-AXIS-00272 ``temp_comp_position_0``, P-AXIS-00273 ``temp_comp_offset_0`` in 0.1 µm and P-AXIS-00274
``temp_comp_coefficient`` in µm/m; infosys.beckhoff.com tccncaxisparameter/15266957451).

Per axis the offset at the basic position (integer 0.1 µm), the basic position (0.1 µm) and the coefficient
(integer µm/m).
"""

from __future__ import annotations

from typing import Any

from thermodrift.compensator.cnc.base import Format, number
from thermodrift.compensator.guard import STATUSES, Step

COLUMNS = ("temp_comp_offset_0_0.1um", "temp_comp_position_0_0.1um", "temp_comp_coefficient_um_per_m")


class Beckhoff(Format):
    """Offset (0.1 µm), basic position (0.1 µm) and coefficient (µm/m) per axis."""

    def header(self) -> list[str]:
        return ["time_s"] + [f"{a.name}.{c}" for a in self.axes for c in COLUMNS] + [f"{a.name}_status"
                                                                                     for a in self.axes]

    def rows(self, step: Step) -> list[list[Any]]:
        lines = [self.line(a, step.written) for a in self.axes]
        ax_status = [max((step.status[i] for i in a.targets)) for a in self.axes]
        return [[number(step.time_s)] + [v for (k0, slope) in lines for v in (
            int(round(k0 * 10.0)), int(round(self.reference_mm * 1e4)), int(round(slope * 1e3)))]
            + [STATUSES[s] for s in ax_status]]


def thermodrift_register_cnc_formats(registry):
    registry.add("cnc", "beckhoff", Beckhoff)
