"""Working conditions from the speed schedule: the project's one speed segmenter and what is built on it.

:func:`speed_segments` cuts a speed schedule into constant-speed stretches; :func:`detect_conditions` labels
them as working conditions and :func:`schedule_windows` cuts them into step / running / stopped
:class:`Window` s, so conditions, the mismatch map and the missing-physics finder see one recording alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Working-condition detection from the speed schedule.
_MEDIAN_WINDOW = 5         # samples; removes isolated spikes before levels are found
_LEVEL_TOL_RPM = 25.0      # two speeds closer than max(this, _LEVEL_TOL_REL * max|speed|) are one level
_LEVEL_TOL_REL = 0.02
_MIN_LEVEL_S = 120.0       # shorter level segments (ramps, blips) join the next level
_MIN_LEVEL_SAMPLES = 3
_LABEL_STEP_RPM = 10       # labels name the level rounded to this, so noise does not change them


def speed_segments(time_s: np.ndarray, speed_rpm: np.ndarray) -> list[tuple[int, int, float]]:
    """Constant-speed stretches ``(start, stop, level rpm)`` (half-open sample ranges) of a speed schedule.

    The project's one speed segmenter (conditions, mismatch windows and calibration start values use it): the
    speed is median-filtered (``_MEDIAN_WINDOW`` samples) and cut into levels that differ by more than
    max(25 rpm, 2 % of the top speed); levels shorter than 120 s (ramps, blips) join the next level, and
    adjacent stretches at the same level are one. The level is the filtered speed's median over the stretch.
    """
    t = np.asarray(time_s, dtype=float)
    v = _median_filter(np.asarray(speed_rpm, dtype=float), _MEDIAN_WINDOW)
    n = len(v)
    if n == 0:
        return []
    tol = max(_LEVEL_TOL_RPM, _LEVEL_TOL_REL * float(np.abs(v).max()))
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    min_len = max(_MIN_LEVEL_SAMPLES, int(math.ceil(_MIN_LEVEL_S / dt))) if dt > 0 else _MIN_LEVEL_SAMPLES
    merged: list[list] = []
    for a, b in _merge_short(_level_starts(v, tol), n, min_len):
        level = float(np.median(v[a:b]))
        if merged and abs(level - merged[-1][2]) <= tol:
            merged[-1][1] = b
            merged[-1][2] = float(np.median(v[merged[-1][0]:b]))
        else:
            merged.append([a, b, level])
    return [(int(a), int(b), float(level)) for a, b, level in merged]


def detect_conditions(time_s: np.ndarray, speed_rpm: np.ndarray) -> np.ndarray:
    """Working-condition labels (object array) from a piecewise-constant speed schedule in rpm.

    Levels come from :func:`speed_segments`. A new condition starts at each change to another nonzero level; a
    stop joins the condition before it; a restart at the same level continues it; leading idle time is
    ``c00_idle``. Labels name the level rounded to 10 rpm.
    """
    v = np.asarray(speed_rpm, dtype=float)
    labels = np.empty(len(v), dtype=object)
    if not len(v):
        return labels
    tol = max(_LEVEL_TOL_RPM, _LEVEL_TOL_REL * float(np.abs(_median_filter(v, _MEDIAN_WINDOW)).max()))
    current, level, k = "c00_idle", None, 0
    for a, b, seg_level in speed_segments(time_s, v):
        if abs(seg_level) > tol and (level is None or abs(seg_level - level) > tol):
            k, level = k + 1, seg_level
            current = f"c{k:02d}_{_LABEL_STEP_RPM * round(seg_level / _LABEL_STEP_RPM)}rpm"
        labels[a:b] = current
    return labels


STEP_WINDOW_S = 900.0  # s: the step window after a speed change, where instant growth, lags and fast modes show


@dataclass(frozen=True)
class Window:
    """A time window [start_s, end_s) in s of a recording, cut by one driver.

    ``driver`` is the role whose signal defines it (speed, cutting_power, ambient, ...) and ``kind`` what it
    holds (speed: ``step``, ``running``, ``stopped``); ``speed_rpm`` is the level of a speed window, else None.
    """

    name: str
    kind: str
    start_s: float
    end_s: float
    driver: str = "speed"
    speed_rpm: float | None = None

    def mask(self, time_s: np.ndarray) -> np.ndarray:
        """True for the times (s) inside the window."""
        return (time_s >= self.start_s) & (time_s < self.end_s)


def schedule_windows(time_s: np.ndarray, speed_rpm: np.ndarray, step_s: float = STEP_WINDOW_S) -> list[Window]:
    """Windows of a speed schedule, on the stretches of :func:`speed_segments`: after each change of level a
    ``step`` window (its first ``step_s`` seconds), then the rest of the stretch as ``running`` or ``stopped``."""
    t = np.asarray(time_s, dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    end_of = lambda i: float(t[i]) if i < len(t) else float(t[-1] + dt)  # noqa: E731 (half-open ends)
    out: list[Window] = []
    prev = None
    for a, b, level in speed_segments(t, speed_rpm):
        label = f"{level:g} rpm" if level > 0 else "stop"
        kind = "running" if level > 0 else "stopped"
        if prev is not None:
            cut = min(int(np.searchsorted(t, t[a] + step_s)), b)
            out.append(Window(f"step {prev:g}→{level:g} rpm at {t[a] / 3600.0:.2f} h", "step", float(t[a]),
                              end_of(cut), speed_rpm=level))
            a = cut
        if a < b:
            out.append(Window(f"{label} from {t[a] / 3600.0:.2f} h", kind, float(t[a]), end_of(b), speed_rpm=level))
        prev = level
    return out


def _median_filter(x: np.ndarray, window: int) -> np.ndarray:
    if len(x) < window:
        return x.copy()
    half = window // 2
    padded = np.pad(x, half, mode="edge")
    return np.median(np.lib.stride_tricks.sliding_window_view(padded, window), axis=1)


def _level_starts(v: np.ndarray, tol: float) -> list[int]:
    """Indices where the speed leaves the current level by more than ``tol``."""
    starts, ref = [0], v[0]
    for i, x in enumerate(v.tolist()):
        if abs(x - ref) > tol:
            starts.append(i)
            ref = x
    return starts


def _merge_short(starts: list[int], n: int, min_len: int) -> list[tuple[int, int]]:
    """Segments [a, b); a segment shorter than ``min_len`` joins the next one (the last joins the previous)."""
    bounds = list(zip(starts, starts[1:] + [n]))
    out: list[tuple[int, int]] = []
    pending: int | None = None
    for i, (a, b) in enumerate(bounds):
        start = a if pending is None else pending
        if b - a < min_len and i < len(bounds) - 1:
            pending = start
            continue
        pending = None
        if b - a < min_len and out:
            out[-1] = (out[-1][0], b)
        else:
            out.append((start, b))
    return out
