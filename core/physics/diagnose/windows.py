"""Time windows cut from every driver of a recording, not from the speed schedule alone.

Each :class:`~thermodrift.core.recording.Window` names the driver that defines it and its kind:

* speed: the schedule windows of the one speed segmenter (:func:`thermodrift.core.recording.schedule_windows`):
  ``step`` (the first 15 min after each speed change), ``running`` (the rest of a running block), ``stopped``;
* cutting power and axis velocity: ``on`` (while the driver is active) and ``after`` (the hour after it stops);
* coolant inlet: ``rising`` / ``falling`` half-cycles of the chiller (merged to at least 10 min);
* ambient: ``warm`` / ``cool`` regimes (above or below its 6 h running mean, at least 1 h long);
* temperature rates: ``fast heating`` / ``fast cooling`` where the fastest channel changes quicker than its
  upper quartile rate.

Windows overlap (a speed step can fall in a warm-ambient regime); times are half-open [start_s, end_s) in s.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from thermodrift.core.recording import Window, schedule_windows

AFTER_S = 3600.0


def _runs(flag: np.ndarray) -> list[tuple[int, int, bool]]:
    """(start, stop, value) of each constant stretch of a boolean array."""
    if not len(flag):
        return []
    change = np.flatnonzero(flag[1:] != flag[:-1]) + 1
    starts, stops = np.r_[0, change], np.r_[change, len(flag)]
    return [(int(a), int(b), bool(flag[a])) for a, b in zip(starts, stops)]


def _end(t: np.ndarray, i: int) -> float:
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    return float(t[i]) if i < len(t) else float(t[-1] + dt)


def activity_windows(t: np.ndarray, values: np.ndarray, driver: str) -> list[Window]:
    """``on`` while |values| exceeds 1 % of its maximum, ``after`` for the hour after each stretch ends."""
    top = float(np.abs(values).max()) if len(values) else 0.0
    if top <= 0:
        return []
    out = []
    for a, b, on in _runs(np.abs(values) > 0.01 * top):
        if on:
            out.append(Window(f"{driver} on from {t[a] / 3600:.2f} h", "on", float(t[a]), _end(t, b), driver))
            if b < len(t):
                stop = min(int(np.searchsorted(t, t[b] + AFTER_S)), len(t))
                out.append(Window(f"{driver} off from {t[b] / 3600:.2f} h", "after", float(t[b]), _end(t, stop),
                                  driver))
    return out


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    return pd.Series(x).rolling(max(n, 1), center=True, min_periods=1).mean().to_numpy()


def _regimes(t: np.ndarray, flag: np.ndarray, driver: str, kinds: tuple[str, str], min_s: float) -> list[Window]:
    """Windows of each stretch of ``flag`` (True: kinds[0]) longer than ``min_s``; shorter ones join the previous."""
    out: list[Window] = []
    for a, b, on in _runs(flag):
        kind = kinds[0] if on else kinds[1]
        if out and (t[min(b, len(t) - 1)] - t[a] < min_s or out[-1].kind == kind):
            last = out.pop()
            out.append(Window(last.name, last.kind, last.start_s, _end(t, b), driver))
            continue
        out.append(Window(f"{driver} {kind} from {t[a] / 3600:.2f} h", kind, float(t[a]), _end(t, b), driver))
    return out


def driver_windows(recording) -> list[Window]:
    """Windows from every driver the recording carries (see the module docstring)."""
    t = recording.time_s
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    out: list[Window] = []
    if recording.speed is not None:
        out += schedule_windows(t, recording.speed.to_numpy(dtype=float))
    for role in ("cutting_power", "axis_velocity"):
        for c in recording.columns(role)[:1]:
            out += activity_windows(t, recording.data[c].to_numpy(dtype=float), role)
    for c in recording.columns("coolant_inlet")[:1]:
        x = _smooth(recording.data[c].to_numpy(dtype=float), int(120 / dt))
        if np.ptp(x) > 0:
            out += _regimes(t, np.gradient(x) > 0, "coolant_inlet", ("rising", "falling"), 600.0)
    for c in recording.columns("ambient")[:1]:
        x = recording.data[c].to_numpy(dtype=float)
        if np.ptp(x) > 0:
            trend = _smooth(x, int(6 * 3600 / dt))
            out += _regimes(t, _smooth(x, int(600 / dt)) > trend, "ambient", ("warm", "cool"), 3600.0)
    temps = recording.temperatures
    if temps.shape[1] and len(t) > 10:
        rate = np.gradient(_smooth_frame(temps.to_numpy(dtype=float), int(300 / dt)), t, axis=0)  # K/s
        fastest = rate[np.arange(len(t)), np.abs(rate).argmax(axis=1)]
        q = np.quantile(np.abs(fastest), 0.75)
        if q > 0:
            for a, b, fast in _runs(np.abs(fastest) > q):
                if fast and t[min(b, len(t) - 1)] - t[a] >= 600.0:
                    kind = "fast heating" if np.mean(fastest[a:b]) > 0 else "fast cooling"
                    out.append(Window(f"{kind} from {t[a] / 3600:.2f} h", kind, float(t[a]), _end(t, b),
                                      "temperature_rate"))
    return out


def _smooth_frame(x: np.ndarray, n: int) -> np.ndarray:
    return pd.DataFrame(x).rolling(max(n, 1), center=True, min_periods=1).mean().to_numpy()


def condition_blocks(recording, rows: np.ndarray, min_blocks: int = 4) -> np.ndarray:
    """Block id per selected row for condition-blocked scoring: contiguous condition runs, else equal time
    blocks when the recording has fewer than ``min_blocks`` runs."""
    labels = recording.conditions().to_numpy()[rows]
    run = np.cumsum(np.r_[True, labels[1:] != labels[:-1]]) - 1 if len(labels) else np.zeros(0, int)
    if run.max(initial=0) + 1 >= min_blocks:
        return run
    return np.minimum((np.arange(len(rows)) * min_blocks) // max(len(rows), 1), min_blocks - 1)


def locate(time_s: np.ndarray, gain: np.ndarray, channels: list[str], use: list[int], windows: list[Window],
           top: int = 3) -> dict[str, list]:
    """Up to ``top`` (channel, window) where a correction removes most of the misfit: ``gain`` (samples,
    channels) is the squared error removed per sample; each window of a channel in ``use`` scores its share of
    that channel's removed error times its excess over the window's length share (at most 10). A finding's
    fields, best first: ``where`` ({``channel``, ``start_s``, ``end_s``}, times in s to 0.1 s) and ``_windows``
    (the windows' names)."""
    out = []
    for j in use:
        g = gain[:, j]
        total = g[g > 0].sum()
        if total <= 0:
            continue
        for w in windows:
            mask = w.mask(time_s)
            if mask.sum() < 2:
                continue
            share = float(g[mask].sum() / total)
            out.append((share * min(share / mask.mean(), 10.0), j, w))
    best = sorted(out, key=lambda x: -x[0])[:top]
    return {"where": [{"channel": channels[j], "start_s": round(float(w.start_s), 1), "end_s": round(float(w.end_s), 1)}
                      for _, j, w in best], "_windows": [w.name for _, _, w in best]}
