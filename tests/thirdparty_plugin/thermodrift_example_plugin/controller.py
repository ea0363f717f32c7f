"""CNC format ``plc_words``: one signed 16-bit register per target in 0.1 µm, as a PLC data block reads it.

A value beyond the register's range (±3276.7 µm) is written at the range's end with the status ``clamped``; the
status column holds the compensator's status per target (``ok``, ``rate_limited``, ``clamped``, ``held``,
``fallback``).
"""

import numpy as np

from thermodrift.compensator.cnc import Format
from thermodrift.compensator.guard import CLAMPED, STATUSES
from thermodrift.core.hookspecs import hookimpl

WORD = 32767  # int16: ±32767 tenths of a µm


class PlcWords(Format):
    """One int16 register per target in 0.1 µm (±3276.7 µm), then the status per target."""

    def header(self):
        return ["time_s"] + [f"{t}_0.1um" for t in self.targets] + [f"{t}_status" for t in self.targets]

    def rows(self, step):
        tenths = np.round(np.asarray(step.written, dtype=float) * 10.0)
        status = np.where(np.abs(tenths) > WORD, np.maximum(step.status, CLAMPED), step.status)
        words = np.clip(tenths, -WORD, WORD).astype(int)
        return [[repr(float(step.time_s))] + [int(w) for w in words] + [STATUSES[s] for s in status]]


@hookimpl
def thermodrift_register_cnc_formats(registry):
    registry.add("cnc", "plc_words", PlcWords)
