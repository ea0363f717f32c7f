"""Sensors: what a simulated machine's instruments would have recorded.

A :class:`TemperatureSensor` reads one node, a weighted mix of nodes (a sensor placed between two lumps), or a
boundary (``ambient``, ``coolant``). Its reading is the first-order-lagged temperature plus a fixed offset
(Pt100 tolerance), white noise, and quantization. A :class:`DisplacementSensor` reads one network output (µm)
with white noise and quantization (dial gauges: 0.5 µm steps; capacitive/laser probes: 0.04–0.07 µm noise).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
import pandas as pd


def _meta(unit: str, low: float | None = None, doc: str = "") -> dict:
    return {"unit": unit, "min": low, "doc": doc}


@dataclass(frozen=True)
class TemperatureSensor:
    """A temperature channel (°C) reading ``node`` (a name, or ``{node: weight}`` weights summing to 1)."""

    name: str
    node: str | Mapping[str, float]
    role: str = "temperature"
    offset_K: float = field(default=0.0, metadata=_meta("K", doc="fixed calibration offset"))
    noise_K: float = field(default=0.01, metadata=_meta("K", 0.0, "white-noise standard deviation"))
    lag_s: float = field(default=0.0, metadata=_meta("s", 0.0, "first-order sensor time constant"))
    resolution_K: float = field(default=0.0, metadata=_meta("K", 0.0, "quantization step (0: none)"))
    location: str = ""

    @property
    def weights(self) -> dict[str, float]:
        """``{node or boundary: weight}`` of what the sensor reads."""
        return {self.node: 1.0} if isinstance(self.node, str) else dict(self.node)


@dataclass(frozen=True)
class DisplacementSensor:
    """A displacement channel (µm) reading network output ``output``."""

    name: str
    output: str
    noise_um: float = field(default=0.05, metadata=_meta("um", 0.0, "white-noise standard deviation"))
    resolution_um: float = field(default=0.0, metadata=_meta("um", 0.0, "quantization step (0: none)"))
    offset_um: float = field(default=0.0, metadata=_meta("um", doc="probe zero offset"))


Sensor = TemperatureSensor | DisplacementSensor


def first_order_lag(x: np.ndarray, time_s: np.ndarray, tau_s: float) -> np.ndarray:
    """Exact response of a first-order lag τ (s) to ``x`` linear between samples, starting in equilibrium.

    Uses the uniform step of ``time_s``; a non-uniform grid falls back to a per-step recursion.
    """
    x = np.asarray(x, dtype=float)
    if tau_s <= 0 or len(x) < 2:
        return x.copy()
    h = np.diff(time_s)
    if np.allclose(h, h[0]):
        from scipy.signal import lfilter, lfiltic  # imported here: ~1 s, not to be paid when plugins load

        a = np.exp(-h[0] / tau_s)
        b0 = 1.0 - tau_s * (1.0 - a) / h[0]  # weight of x_{k+1} under a linear (first-order-hold) input
        b1 = (1.0 - a) - b0
        y, _ = lfilter([b0, b1], [1.0, -a], x, zi=lfiltic([b0, b1], [1.0, -a], y=[x[0]], x=[x[0]]))
        return y
    y = np.empty_like(x)
    y[0] = x[0]
    for k, hk in enumerate(h):
        a = np.exp(-hk / tau_s)
        b0 = 1.0 - tau_s * (1.0 - a) / hk
        y[k + 1] = a * y[k] + b0 * x[k + 1] + ((1.0 - a) - b0) * x[k]
    return y


def temperature_reading(sensor: TemperatureSensor, values: Mapping[str, np.ndarray], time_s: np.ndarray,
                        offset: bool = True) -> np.ndarray:
    """Noise-free reading (°C) of ``sensor``: its weighted node or boundary temperatures ``values`` (by name),
    first-order-lagged, plus its offset (``offset=False``: without it, as the calibration projects it)."""
    true = sum(w * np.asarray(values[n], dtype=float) for n, w in sensor.weights.items())
    lagged = first_order_lag(true, time_s, sensor.lag_s) if sensor.lag_s > 0 else np.asarray(true, dtype=float)
    return lagged + sensor.offset_K if offset else lagged


def quantize(x: np.ndarray, step: float) -> np.ndarray:
    """Round to multiples of ``step`` (no change for step 0)."""
    return np.round(x / step) * step if step > 0 else x


def measure(sensors: tuple[Sensor, ...], sources: pd.DataFrame, displacements: pd.DataFrame,
            seed: int | None) -> pd.DataFrame:
    """Sensor readings (°C, µm) indexed like ``sources``.

    ``sources`` holds node temperatures and the boundary columns ``ambient`` and ``coolant`` (°C);
    ``displacements`` the network outputs (µm). ``seed`` fixes the noise (None: noise-free readings, but offsets,
    lags and quantization still apply).
    """
    rng = np.random.default_rng(seed) if seed is not None else None
    time_s = sources.index.to_numpy(dtype=float)
    columns: dict[str, np.ndarray] = {}
    for s in sensors:
        if isinstance(s, TemperatureSensor):
            value = temperature_reading(s, {n: sources[n].to_numpy() for n in s.weights}, time_s)
            noise = s.noise_K
            resolution = s.resolution_K
        else:
            value = displacements[s.output].to_numpy() + s.offset_um
            noise, resolution = s.noise_um, s.resolution_um
        if rng is not None and noise > 0:
            value = value + rng.normal(0.0, noise, len(value))
        columns[s.name] = quantize(value, resolution)
    return pd.DataFrame(columns, index=sources.index)
