"""Machining programmes, room air, chiller and sensors for the independent generators (own forms throughout).

Everything here is drawn from one ``numpy`` generator per case; nothing is shared with the library's
scenarios or sensor models. Times in s, speeds in rpm, powers in W, feeds in mm/min, temperatures in °C.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DAY_S = 86400.0


@dataclass
class Programme:
    """Inputs on the integration grid ``t`` (s, step ``h``): spindle speed (rpm), cutting power (W) and
    absolute feed (mm/min), each held over a step; ``n_max`` the spindle's top speed."""

    t: np.ndarray
    h: float
    speed: np.ndarray
    cutting_W: np.ndarray
    feed: np.ndarray
    n_max: float


def programme(rng: np.random.Generator, hours: float, h: float, cutting: bool, axis: bool) -> Programme:
    """About ``hours`` of work: idle start, runs at drawn speed levels (some as stepped warm-up ramps), stops;
    with ``cutting``, part cycles (roughing, finishing, tool change) in some runs; with ``axis``, reciprocating
    axis moves in some stops and runs (feed drawn per move, 2–15 m/min, duty 30–80 %)."""
    n_max = float(rng.choice([6000.0, 8000.0, 10000.0, 12000.0]))
    steps = int(round(hours * 3600.0 / h)) + 1
    t = np.arange(steps) * h
    speed = np.zeros(steps)
    cut = np.zeros(steps)
    feed = np.zeros(steps)
    i = int(rng.uniform(0.3, 0.8) * 3600 / h)
    levels = np.array([0.2, 0.35, 0.5, 0.65, 0.8, 1.0])
    while i < steps:
        run = int(rng.uniform(0.8, 3.0) * 3600 / h)
        seg = slice(i, min(i + run, steps))
        if rng.random() < 0.2:  # a stepped warm-up ramp: 4–6 levels of 10–20 min
            k = int(rng.integers(4, 7))
            lv = np.sort(rng.choice(levels, k, replace=True))
            dwell = int(rng.uniform(600, 1200) / h)
            for j, v in enumerate(lv):
                speed[i + j * dwell: min(i + (j + 1) * dwell, steps)] = v * n_max
            run = min(run, k * dwell)
            seg = slice(i, min(i + run, steps))
        else:
            speed[seg] = float(rng.choice(levels)) * n_max
            if cutting and rng.random() < 0.55:
                cut[seg] = _part_cycles(rng, seg.stop - seg.start, h)
        if axis and rng.random() < 0.4:
            feed[seg] = _reciprocation(rng, seg.stop - seg.start, h)
        i += run
        stop = int(rng.uniform(0.4, 2.0) * 3600 / h)
        seg = slice(i, min(i + stop, steps))
        if axis and rng.random() < 0.5:  # axis moves with the spindle idle (probing, pallet work, warm-up of X)
            feed[seg] = _reciprocation(rng, seg.stop - seg.start, h)
        i += stop
    return Programme(t, h, speed, cut, feed, n_max)


def _part_cycles(rng: np.random.Generator, n: int, h: float) -> np.ndarray:
    """Cutting power (W) of repeated part cycles: roughing at P, finishing at 0.2–0.4 P, tool change and
    part change at 0; cycle 4–12 min, P 1.5–7 kW, each cycle ±15 %."""
    out = np.zeros(n)
    p = rng.uniform(1500.0, 7000.0)
    t_cycle = rng.uniform(240.0, 720.0)
    rough, finish = rng.uniform(0.35, 0.6), rng.uniform(0.15, 0.3)
    t = 0.0
    while t < n * h:
        scale = rng.uniform(0.85, 1.15)
        for share, level in ((rough, 1.0), (finish, rng.uniform(0.2, 0.4)), (1 - rough - finish, 0.0)):
            a, b = int(t / h), int((t + share * t_cycle) / h)
            out[a:min(b, n)] = p * level * scale
            t += share * t_cycle
    return out


def _reciprocation(rng: np.random.Generator, n: int, h: float) -> np.ndarray:
    """|feed| (mm/min) of back-and-forth moves: feed 2000–15000 mm/min for a duty of 30–80 % of the time."""
    f = rng.uniform(2000.0, 15000.0)
    duty = rng.uniform(0.3, 0.8)
    period = rng.uniform(30.0, 300.0)
    phase = (np.arange(n) * h / period) % 1.0
    return np.where(phase < duty, f, 0.0)


def room(rng: np.random.Generator, t: np.ndarray, lively: bool, start_hour: float) -> np.ndarray:
    """Hall air (°C): daily cycle (an asymmetric sine: warming by day, slow night cooling) plus, when
    ``lively``, an HVAC thermostat cycling with hysteresis (0.3–1 K band, 15–60 min) and a morning step of the
    heating schedule; a quiet hall swings 0.1–0.4 K a day and has no HVAC cycling."""
    mean = rng.uniform(18.0, 24.0)
    amp = rng.uniform(1.2, 3.0) if lively else rng.uniform(0.1, 0.4)
    hour = (start_hour + t / 3600.0) % 24.0
    phase = 2 * np.pi * (hour - rng.uniform(13.0, 17.0)) / 24.0
    air = mean + amp * (np.cos(phase) + 0.25 * np.cos(2 * phase + 0.7))
    if lively:
        band = rng.uniform(0.3, 1.0)
        rise, fall = rng.uniform(10.0, 40.0) * 60.0, rng.uniform(5.0, 20.0) * 60.0
        hvac = np.empty_like(t)
        level, up, dt = 0.0, True, float(t[1] - t[0])
        for k in range(len(t)):  # the thermostat's sawtooth: warms at band/rise, cools at band/fall, hysteresis
            level += (band / rise if up else -band / fall) * dt
            if level >= band / 2:
                up = False
            elif level <= -band / 2:
                up = True
            hvac[k] = level
        on_hours = (hour > rng.uniform(5.0, 7.0)) & (hour < rng.uniform(17.0, 20.0))
        air = air + hvac + rng.uniform(0.3, 0.8) * on_hours
    return air


@dataclass
class Chiller:
    """A tank chiller with on/off hysteresis: the tank (J/K) gains the returned jacket heat, pump heat and
    heat from the hall; the compressor removes ``cooling_W`` while on; on above set + band/2, off below
    set − band/2. ``steady``: a precision (inverter) chiller holding the inlet at ``set_degC``."""

    set_degC: float
    band_K: float
    tank_J_K: float
    cooling_W: float
    pump_W: float
    hall_W_K: float
    steady: bool
    tank: float = 0.0
    on: bool = False

    @classmethod
    def draw(cls, rng: np.random.Generator, steady: bool) -> "Chiller":
        c = cls(float(rng.uniform(19.0, 23.0)), float(rng.uniform(0.6, 1.6)), float(rng.uniform(1.5e5, 5e5)),
                float(rng.uniform(900.0, 2500.0)), float(rng.uniform(40.0, 120.0)), float(rng.uniform(3.0, 10.0)),
                steady)
        c.tank = c.set_degC + float(rng.uniform(-0.5, 0.5)) * c.band_K
        return c

    def inlet(self) -> float:
        return self.set_degC if self.steady else self.tank

    def step(self, returned_W: float, hall_degC: float, h: float) -> None:
        if self.steady:
            return
        if self.tank > self.set_degC + self.band_K / 2:
            self.on = True
        elif self.tank < self.set_degC - self.band_K / 2:
            self.on = False
        q = returned_W + self.pump_W + self.hall_W_K * (hall_degC - self.tank) - (self.cooling_W if self.on else 0.0)
        self.tank += q * h / self.tank_J_K


def lagged(x: np.ndarray, tau_s: float, h: float) -> np.ndarray:
    """First-order lag (time constant ``tau_s``) of a series held over steps of ``h`` s, exact per step."""
    if tau_s <= 0:
        return x.copy()
    a = np.exp(-h / tau_s)
    out = np.empty_like(x)
    y = x[0]
    for k in range(len(x)):
        y = a * y + (1 - a) * x[k]
        out[k] = y
    return out


def pad_sensor(surface: np.ndarray, air: np.ndarray, tau_s: float, air_share: float, h: float) -> np.ndarray:
    """A sensor on a pad (magnet on paint): a small mass joined to the surface and, by ``air_share`` of its
    total conductance, to the air; time constant ``tau_s``. Reads a lagged mix of surface and air."""
    drive = (1 - air_share) * surface + air_share * air
    return lagged(drive, tau_s, h)


def sample(x: np.ndarray, every: int, mean: bool = False) -> np.ndarray:
    """Every ``every``-th value of a grid series; ``mean``: the mean over the interval ending there (a logger
    that averages, as CNC power and feed logs do)."""
    if not mean:
        return x[::every]
    c = np.concatenate([[0.0], np.cumsum(x)])
    idx = np.arange(0, len(x), every)
    lo = np.maximum(idx - every + 1, 0)
    return (c[idx + 1] - c[lo]) / (idx + 1 - lo)
