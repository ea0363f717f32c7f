"""Recordings: a table plus a YAML manifest -> channels by role in canonical units.

Five modules, one job each: :mod:`~thermodrift.core.recording.types` (the :class:`Recording` type and the
roles), :mod:`~thermodrift.core.recording.conditions` (working conditions from the speed schedule: the one
speed segmenter, and the schedule windows built on it), :mod:`~thermodrift.core.recording.loading`
(reading a table and its manifest, with validation), :mod:`~thermodrift.core.recording.runs` (several tables,
sheets or run-column blocks as one machine's independent runs) and :mod:`~thermodrift.core.recording.file_checks`
(the loader's bounded checks of a file before a parser reads it). Every public name is importable from here.
"""

from thermodrift.core.recording.conditions import (STEP_WINDOW_S, Window, detect_conditions, schedule_windows,
                                                 speed_segments)
from thermodrift.core.recording.loading import (MAX_NAN_RUN, MIN_ROWS, TIME_UNITS, UNITLESS, UNITS, Manifest, PlausibilityWarning,
                                              load_recording, read_manifest)
from thermodrift.core.recording.types import (ERROR_UNITS, HEAT_INPUT_ROLES, INPUT_ROLES, ROLES, TARGET_ROLES,
                                            TEMPERATURE_ROLES, TIME_INDEX, Channel, Recording)

__all__ = ["ROLES", "TEMPERATURE_ROLES", "HEAT_INPUT_ROLES", "INPUT_ROLES", "TARGET_ROLES", "ERROR_UNITS", "TIME_INDEX", "MIN_ROWS", "MAX_NAN_RUN", "UNITS", "UNITLESS", "TIME_UNITS", "Manifest", "read_manifest", "STEP_WINDOW_S", "Channel",
           "Recording", "Window", "PlausibilityWarning", "detect_conditions", "load_recording", "schedule_windows",
           "speed_segments"]
