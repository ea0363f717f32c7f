"""Recordings: a table plus a YAML manifest -> channels by role in canonical units.

Three modules, one job each: :mod:`~thermodrift.core.recording.types` (the :class:`Recording` type and the
roles), :mod:`~thermodrift.core.recording.conditions` (working conditions from the speed schedule: the one
speed segmenter) and :mod:`~thermodrift.core.recording.loading` (reading a table and its manifest, with
validation). Every public name is importable from here.
"""

from thermodrift.core.recording.conditions import detect_conditions, speed_segments
from thermodrift.core.recording.loading import MAX_NAN_RUN, MIN_ROWS, PlausibilityWarning, load_recording
from thermodrift.core.recording.types import ROLES, TEMPERATURE_ROLES, TIME_INDEX, Channel, Recording

__all__ = ["ROLES", "TEMPERATURE_ROLES", "TIME_INDEX", "MIN_ROWS", "MAX_NAN_RUN", "Channel", "Recording",
           "PlausibilityWarning", "detect_conditions", "load_recording", "speed_segments"]
