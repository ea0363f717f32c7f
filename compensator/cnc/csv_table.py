"""CNC format ``csv``: ``time_s``, then per target ``<target>_um`` (written), ``<target>_raw_um`` (the model's
prediction, µm) and ``<target>_status``; a temperature target (its ``axes`` entry has ``unit: degC``) writes
``<target>_degC`` and ``<target>_raw_degC`` instead."""

from __future__ import annotations

from typing import Any

from thermodrift.compensator.cnc.base import Format, number
from thermodrift.compensator.guard import STATUSES, Step


class CsvTable(Format):
    """Every written value (µm) with the model's raw prediction and the status, per target."""

    units = None  # displacements and temperatures

    def header(self) -> list[str]:
        return ["time_s"] + [f"{t}_{s}" for t, u in zip(self.targets, self.target_units)
                             for s in (u, f"raw_{u}", "status")]

    def rows(self, step: Step) -> list[list[Any]]:
        return [[number(step.time_s)] + [x for i in range(len(self.targets)) for x in (
            number(step.written[i]), number(step.raw[i]), STATUSES[step.status[i]])]]


def thermodrift_register_cnc_formats(registry):
    registry.add("cnc", "csv", CsvTable)
