"""A tiny, seeded thermal recording for the conformance checks (300 samples, built in milliseconds).

A spindle runs a speed schedule (rpm). Its heat drives two first-order lags: a fast one (bearings,
τ = 20 min) and a slow one (structure, τ = 90 min). Four temperature sensors (°C) read mixtures of the two
lags above a slowly drifting ambient, one of them (``T_cabinet``) only the ambient, so selectors have an
irrelevant channel to drop. Two displacement channels (µm) are linear in the lags with opposite-sign paths,
like a real spindle's axial and radial drift.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pandas as pd

SAMPLE_S = 60.0
SPEED_SCHEDULE_RPM = (0, 2000, 4000, 0, 6000, 3000)  # 50 samples each
TAU_FAST_S, TAU_SLOW_S = 1200.0, 5400.0
# Sensor = ambient + a·fast + b·slow + noise (°C); displacement = c·fast + d·slow + noise (µm).
SENSORS = {"T_front_bearing": (1.0, 0.2), "T_rear_bearing": (0.6, 0.4), "T_column": (0.1, 0.9), "T_cabinet": (0.0, 0.0)}
DISPLACEMENTS = {"disp_z_um": (3.0, 2.5), "disp_x_um": (-0.8, 1.5)}


@lru_cache(maxsize=8)
def _table(seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    speed = np.repeat(np.asarray(SPEED_SCHEDULE_RPM, dtype=float), 50)
    n = speed.size
    time_s = np.arange(n) * SAMPLE_S
    heat_K = 15.0 * (speed / 6000.0) ** 1.5  # steady-state rise of the fast lag (K)
    fast, slow = np.zeros(n), np.zeros(n)
    a_fast, a_slow = np.exp(-SAMPLE_S / TAU_FAST_S), np.exp(-SAMPLE_S / TAU_SLOW_S)
    for i in range(1, n):  # exact discretisation of dT/dt = (u - T)/τ for a piecewise-constant input
        fast[i] = a_fast * fast[i - 1] + (1 - a_fast) * heat_K[i - 1]
        slow[i] = a_slow * slow[i - 1] + (1 - a_slow) * 0.6 * heat_K[i - 1]
    ambient = 20.0 + 0.8 * np.sin(2 * np.pi * time_s / 86400.0) + np.cumsum(rng.normal(0, 0.01, n))
    table = {"speed_rpm": speed, "T_ambient": ambient}
    for name, (a, b) in SENSORS.items():
        table[name] = ambient + a * fast + b * slow + rng.normal(0, 0.03, n)
    table["T_cabinet"] += np.cumsum(rng.normal(0, 0.02, n))
    for name, (c, d) in DISPLACEMENTS.items():
        table[name] = c * fast + d * slow + rng.normal(0, 0.2, n)
    return pd.DataFrame(table, index=pd.Index(time_s, name="time_s"))


def tiny_frames(seed: int = 0) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``(X, y)``: temperatures in °C and displacements in µm of the tiny recording, indexed by time in s."""
    table = _table(seed)
    return table[list(SENSORS)].copy(), table[list(DISPLACEMENTS)].copy()


def tiny_recording(seed: int = 0):
    """The tiny recording as a :class:`thermodrift.core.recording.Recording`."""
    from thermodrift.core.recording import Channel, Recording

    channels = {"speed_rpm": Channel("speed_rpm", "speed", "rpm", {}),
                "T_ambient": Channel("T_ambient", "ambient", "degC", {})}
    for name in SENSORS:
        channels[name] = Channel(name, "temperature", "degC", {"location": name[2:]})
    for name in DISPLACEMENTS:
        channels[name] = Channel(name, "displacement", "um", {"axis": name.split("_")[1]})
    return Recording(_table(seed).copy(), channels, source="<thermodrift.testing tiny recording>")

