"""Schedule windows: the finder and the mismatch map cut a recording on the one speed segmenter, as one type."""

from __future__ import annotations

import numpy as np
import pandas as pd

from thermodrift.core.physics import mismatch
from thermodrift.core.physics.diagnose.windows import driver_windows
from thermodrift.core.recording import Channel, Recording, Window, schedule_windows, speed_segments


def _recording(dt: float = 10.0) -> Recording:
    """6 h at 10 s: stop, 3000 rpm with two 20 s blips to 3600 rpm, 6000 rpm with a 30 s dip to 0, stop; cutting
    from 1.1 h to 2.5 h."""
    blocks = [(0.0, 3600), (3000.0, 7200), (6000.0, 7200), (0.0, 3600)]
    speed = np.concatenate([np.full(int(d / dt), rpm) for rpm, d in blocks])
    t = np.arange(len(speed)) * dt
    for at, width, rpm in ((5000.0, 20.0, 3600.0), (8000.0, 20.0, 3600.0), (14000.0, 30.0, 0.0)):
        speed[(t >= at) & (t < at + width)] = rpm
    cutting = np.where((t >= 4000.0) & (t < 9000.0), 800.0, 0.0)
    data = pd.DataFrame({"rpm": speed, "P": cutting, "T": 20.0 + np.cumsum(speed) * 1e-6,
                         "d": np.cumsum(speed) * 1e-5}, index=pd.Index(t, name="time_s"))
    channels = {"rpm": Channel("rpm", "speed", "rpm"), "P": Channel("P", "cutting_power", "W"),
                "T": Channel("T", "temperature", "degC"), "d": Channel("d", "displacement", "um")}
    return Recording(data, channels)


def test_short_blips_cut_no_window_and_the_finder_and_the_mismatch_map_agree():
    rec = _recording()
    t, speed = rec.time_s, rec.speed.to_numpy()
    expected = schedule_windows(t, speed)
    assert [w.kind for w in expected] == ["stopped", "step", "running", "step", "running", "step", "stopped"]
    assert len(speed_segments(t, speed)) == 4  # the blips join the level they interrupt
    finder = [w for w in driver_windows(rec) if w.driver == "speed"]
    assert finder == expected
    assert mismatch.schedule_windows(t, speed) == expected


def test_windows_of_every_driver_are_the_one_window_type():
    rec = _recording()
    windows = driver_windows(rec)
    assert windows and all(type(w) is Window for w in windows)
    assert {w.driver for w in windows} == {"speed", "cutting_power"}
    w = windows[1]
    mask = w.mask(rec.time_s)
    assert rec.time_s[mask].min() == w.start_s and rec.time_s[mask].max() < w.end_s
    assert w.speed_rpm is not None and all(v.speed_rpm is None for v in windows if v.driver != "speed")
