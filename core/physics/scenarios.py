"""Operating scenarios: what the machine is asked to do and the environment it stands in.

A :class:`Scenario` is a table on a time grid (index ``time_s``) of the input signals, held constant over
each step (zero-order hold):

============================  ========  ==================================================
column                        unit      default
============================  ========  ==================================================
``speed_rpm``                 rpm       0
``ambient_degC``              °C        20
``coolant_inlet_degC``        °C        the ambient temperature
``coolant_flow``              0…1       1 (fraction of the nominal coolant flow)
``cutting_power_W``           W         0
``axis_velocity_mm_min``      mm/min    0
``condition``                 label     "" (the working condition, for condition-held-out splits)
============================  ========  ==================================================

Builders: :func:`blocks` (constant-input blocks, ISO 230-3 style) with ambient profiles
(:func:`constant`, :func:`daily_cycle`, :func:`warm_ventilation`, :func:`steps`) and chiller cycling
(:func:`chiller_cycling`); named programmes in :data:`SCENARIOS` (:func:`build` by name): the FL_THERMAL
programme, ISO 230-3 constant speed / speed spectrum / environmental variation, the seed studies' duty cycles.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from thermodrift.core.errors import InputError

SIGNALS = ("speed_rpm", "ambient_degC", "coolant_inlet_degC", "coolant_flow", "cutting_power_W",
           "axis_velocity_mm_min")
Profile = Callable[[np.ndarray], np.ndarray]  # time in s -> °C


class Scenario:
    """Input signals on a time grid; see the module docstring for the columns. Missing columns get defaults."""

    def __init__(self, frame: pd.DataFrame, name: str = "scenario"):
        frame = frame.copy()
        frame.index = pd.Index(np.asarray(frame.index, dtype=float), name="time_s")
        if len(frame) < 2:
            raise InputError(f"scenario {name!r} needs at least two time steps")
        if not np.all(np.diff(frame.index.to_numpy()) > 0):
            raise InputError(f"scenario {name!r}: time must increase strictly")
        unknown = set(frame.columns) - set(SIGNALS) - {"condition"}
        if unknown:
            raise InputError(f"scenario {name!r}: unknown columns {sorted(unknown)}", hint=f"use {', '.join(SIGNALS)}")
        frame = frame.assign(**{c: d for c, d in (("speed_rpm", 0.0), ("ambient_degC", 20.0), ("coolant_flow", 1.0),
                                                  ("cutting_power_W", 0.0), ("axis_velocity_mm_min", 0.0),
                                                  ("condition", "")) if c not in frame})
        if "coolant_inlet_degC" not in frame:
            frame["coolant_inlet_degC"] = frame["ambient_degC"]
        values = frame[list(SIGNALS)].to_numpy(dtype=float)
        if not np.all(np.isfinite(values)):
            raise InputError(f"scenario {name!r}: signals must be finite")
        if (frame["speed_rpm"] < 0).any() or (frame["cutting_power_W"] < 0).any():
            raise InputError(f"scenario {name!r}: speed and cutting power must be ≥ 0")
        if ((frame["coolant_flow"] < 0) | (frame["coolant_flow"] > 1)).any():
            raise InputError(f"scenario {name!r}: coolant_flow is a fraction in [0, 1]")
        self.frame = frame[[*SIGNALS, "condition"]]
        self.name = name

    @property
    def time_s(self) -> np.ndarray:
        return self.frame.index.to_numpy()

    @property
    def dt_s(self) -> float:
        """The (median) time step in s."""
        return float(np.median(np.diff(self.time_s)))

    @property
    def hours(self) -> float:
        return float(self.time_s[-1] - self.time_s[0]) / 3600.0

    def __len__(self) -> int:
        return len(self.frame)

    def __repr__(self) -> str:
        return f"Scenario({self.name!r}, {len(self)} steps of {self.dt_s:g} s, {self.hours:.1f} h)"

    def resample(self, dt_s: float) -> "Scenario":
        """The same programme on a uniform grid of ``dt_s`` (values held from the last earlier sample)."""
        t = np.arange(self.time_s[0], self.time_s[-1] + 1e-9, dt_s)
        idx = np.searchsorted(self.time_s, t, side="right") - 1
        frame = self.frame.iloc[idx].set_axis(pd.Index(t, name="time_s"))
        return Scenario(frame, self.name)

    def head(self, hours: float) -> "Scenario":
        """The first ``hours`` of the scenario."""
        keep = self.time_s <= self.time_s[0] + hours * 3600.0 + 1e-9
        return Scenario(self.frame[keep], self.name)

    @classmethod
    def from_recording(cls, recording, ambient_degC: float = 20.0, speed_step_rpm: float = 10.0) -> "Scenario":
        """The inputs of a measured Recording: speed, ambient, coolant inlet, cutting power, axis velocity.

        Speeds are rounded to ``speed_step_rpm`` so that a measured, slightly noisy speed still gives a few
        operating levels (each distinct level costs one matrix exponential). Missing ambient: ``ambient_degC``.
        """
        frame = pd.DataFrame(index=pd.Index(recording.time_s, name="time_s"))
        for role, col in (("speed", "speed_rpm"), ("ambient", "ambient_degC"),
                          ("coolant_inlet", "coolant_inlet_degC"), ("cutting_power", "cutting_power_W"),
                          ("axis_velocity", "axis_velocity_mm_min")):
            cols = recording.columns(role)
            if cols:
                frame[col] = recording.frame(role)[cols[0]].to_numpy(dtype=float)
        if "speed_rpm" in frame and speed_step_rpm > 0:
            frame["speed_rpm"] = np.round(frame["speed_rpm"].clip(lower=0.0) / speed_step_rpm) * speed_step_rpm
        if "ambient_degC" not in frame:
            frame["ambient_degC"] = ambient_degC
        frame["condition"] = recording.conditions().to_numpy().astype(str)
        return cls(frame, getattr(recording, "source", "recording"))


# --- ambient and coolant profiles (vectorised functions of time in s) -------------------------------------------

def constant(value_degC: float = 20.0) -> Profile:
    """A constant temperature."""
    return lambda t: np.full(len(t), float(value_degC))


def daily_cycle(low_degC: float = 17.0, high_degC: float = 27.0, peak_hour: float = 15.0,
                start_hour: float = 8.0) -> Profile:
    """A sinusoidal 24 h cycle between ``low`` and ``high`` peaking at ``peak_hour``; t = 0 is ``start_hour``."""
    mean, amp = (high_degC + low_degC) / 2, (high_degC - low_degC) / 2
    return lambda t: mean + amp * np.cos(2 * np.pi * (t / 3600.0 + start_hour - peak_hour) / 24.0)


def warm_ventilation(start_degC: float = 30.0, settled_degC: float = 24.0, tau_h: float = 3.0,
                     swing_K: float = 0.6, period_h: float = 1.5) -> Profile:
    """Warm natural ventilation: from ``start`` relaxing to ``settled`` (τ h), with gusts of ±``swing`` K."""
    return lambda t: (settled_degC + (start_degC - settled_degC) * np.exp(-t / (tau_h * 3600.0))
                      + swing_K * np.sin(2 * np.pi * t / (period_h * 3600.0)))


def steps(levels_degC: Sequence[float], hours: Sequence[float]) -> Profile:
    """Piecewise-constant levels, each held for its hours (the last one held to the end)."""
    edges = np.cumsum(np.asarray(hours, dtype=float))[:-1] * 3600.0
    levels = np.asarray(levels_degC, dtype=float)
    return lambda t: levels[np.searchsorted(edges, t, side="right")]


def chiller_cycling(setpoint_degC: float = 20.0, hysteresis_K: float = 0.5, warm_rate_K_min: float = 0.08,
                    cool_rate_K_min: float = 0.12, phase: float = 0.0) -> Profile:
    """Coolant supply of an on/off chiller: a triangle between setpoint ± hysteresis.

    The tank warms at ``warm_rate`` while the compressor is off and cools at ``cool_rate`` while it is on, so
    the period is 2h/warm + 2h/cool minutes (≈ 20 min for the defaults, within the usual 5–30 min).
    ``phase`` (0…1) shifts the cycle.
    """
    rise_s = 2 * hysteresis_K / warm_rate_K_min * 60.0
    fall_s = 2 * hysteresis_K / cool_rate_K_min * 60.0
    period = rise_s + fall_s

    def profile(t: np.ndarray) -> np.ndarray:
        x = np.mod(np.asarray(t, dtype=float) + phase * period, period)
        up = setpoint_degC - hysteresis_K + 2 * hysteresis_K * x / rise_s
        down = setpoint_degC + hysteresis_K - 2 * hysteresis_K * (x - rise_s) / fall_s
        return np.where(x < rise_s, up, down)
    return profile


# --- constant-input blocks ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Block:
    """Constant inputs for ``hours``; ``condition`` labels the block (default: inherited from the previous run)."""

    hours: float
    speed_rpm: float = 0.0
    cutting_power_W: float = 0.0
    axis_velocity_mm_min: float = 0.0
    coolant_flow: float = 1.0
    condition: str | None = None


def blocks(programme: Sequence[Block], dt_s: float, *, ambient: Profile | None = None,
           coolant: Profile | None = None, name: str = "blocks") -> Scenario:
    """A scenario from constant-input blocks on a uniform grid of ``dt_s``.

    A block without a ``condition`` takes "<speed>rpm" when it runs and otherwise the previous block's label,
    so a stop belongs to the run it cools down from (the held-out unit of the FL_THERMAL protocol).
    """
    if dt_s <= 0 or not programme:
        raise InputError("blocks need a positive dt_s and at least one block")
    ends = np.cumsum([b.hours * 3600.0 for b in programme])
    t = np.arange(0.0, ends[-1] + 1e-9, dt_s)
    which = np.minimum(np.searchsorted(ends, t, side="right"), len(programme) - 1)
    labels, last = [], "idle"
    for b in programme:
        last = b.condition or (f"{b.speed_rpm:g}rpm" if b.speed_rpm > 0 else last)
        labels.append(last)
    table = np.array([[b.speed_rpm, b.cutting_power_W, b.axis_velocity_mm_min, b.coolant_flow] for b in programme])
    ambient_degC = (ambient or constant(20.0))(t)
    frame = pd.DataFrame({
        "speed_rpm": table[which, 0], "cutting_power_W": table[which, 1], "axis_velocity_mm_min": table[which, 2],
        "coolant_flow": table[which, 3], "ambient_degC": ambient_degC,
        "coolant_inlet_degC": coolant(t) if coolant is not None else ambient_degC,
        "condition": np.asarray(labels, dtype=object)[which],
    }, index=pd.Index(t, name="time_s"))
    return Scenario(frame, name)


def concat(parts: Sequence[Scenario], name: str = "sessions") -> Scenario:
    """Scenarios one after the other on one time axis (each part's times shifted to follow the previous)."""
    frames, start = [], 0.0
    for p in parts:
        f = p.frame.copy()
        f.index = f.index - f.index[0] + start
        frames.append(f if not frames else f.iloc[1:])
        start = f.index[-1]
    return Scenario(pd.concat(frames), name)


# --- named programmes --------------------------------------------------------------------------------------------

def fl_thermal(dt_s: float = 15.0, ambient: Profile | None = None) -> Scenario:
    """The FL_THERMAL speed programme (46.3 h): 4 h runs at 1250/2500/3750/5000/3500 rpm each followed by a
    4 h stop, then 500 and 1500 rpm (2 h), 2500 and 4500 rpm (1 h), stop; ambient ≈ 25.5–27 °C daily."""
    runs = [Block(0.129), *[b for n in (1250, 2500, 3750, 5000, 3500) for b in (Block(4, n), Block(4))],
            Block(2, 500), Block(2, 1500), Block(1, 2500), Block(1, 4500), Block(0.179)]
    return blocks(runs, dt_s, ambient=ambient or daily_cycle(25.5, 27.0, start_hour=10.0), name="fl_thermal")


def iso230_3_constant_speed(speed_rpm: float = 6000.0, hours_on: float = 4.0, hours_off: float = 4.0,
                            dt_s: float = 30.0, ambient: Profile | None = None) -> Scenario:
    """ISO 230-3: spindle at constant speed for ``hours_on``, then stopped for ``hours_off``."""
    return blocks([Block(0.25), Block(hours_on, speed_rpm), Block(hours_off)], dt_s, ambient=ambient,
                  name="iso230_3_constant_speed")


def iso230_3_speed_spectrum(speeds_rpm: Sequence[float] = (1500, 3000, 4500, 6000), hours_on: float = 3.0,
                            hours_off: float = 3.0, dt_s: float = 30.0, ambient: Profile | None = None) -> Scenario:
    """ISO 230-3 speed spectrum as separate runs: each speed for ``hours_on``, then a stop of ``hours_off``."""
    prog = [Block(0.25)] + [b for n in speeds_rpm for b in (Block(hours_on, n), Block(hours_off))]
    return blocks(prog, dt_s, ambient=ambient, name="iso230_3_speed_spectrum")


def iso230_3_environmental(hours: float = 24.0, dt_s: float = 60.0, low_degC: float = 17.0,
                           high_degC: float = 27.0) -> Scenario:
    """ISO 230-3 environmental temperature variation error (ETVE): spindle stopped over ≥ one daily cycle."""
    return blocks([Block(hours, condition="etve")], dt_s, ambient=daily_cycle(low_degC, high_degC),
                  name="iso230_3_environmental")


def s1_duty(dt_s: float = 60.0, speed_rpm: float = 2000.0, cutting_power_W: float = 4000.0,
            ambient: Profile | None = None, condition: str | None = None) -> Scenario:
    """Study S1 duty cycle: 3 h cutting, 1 h stop, 4 h cutting (8 h)."""
    c = condition
    return blocks([Block(3, speed_rpm, cutting_power_W, condition=c), Block(1, condition=c),
                   Block(4, speed_rpm, cutting_power_W, condition=c)], dt_s, ambient=ambient, name="s1_duty")


def s1_validation(dt_s: float = 60.0, speed_rpm: float = 2000.0, cutting_power_W: float = 4000.0,
                  ambient: Profile | None = None, condition: str | None = "validation") -> Scenario:
    """Study S1 validation cycle: 3 h cutting / 1 h stop / 2 h / 10 min stop + 1 part / 50 min stop + 1 part."""
    part = 10.0 / 60.0
    c, run = condition, (speed_rpm, cutting_power_W)
    prog = [Block(3, *run, condition=c), Block(1, condition=c), Block(2, *run, condition=c),
            Block(10 / 60, condition=c), Block(part, *run, condition=c), Block(50 / 60, condition=c),
            Block(part, *run, condition=c), Block(0.5, condition=c)]
    return blocks(prog, dt_s, ambient=ambient, name="s1_validation")


def s1_conditions(dt_s: float = 60.0, rest_hours: float = 12.0) -> Scenario:
    """Study S1's three ambient conditions (≈ 20 °C constant; warm ventilation from 30 °C; 17–27 °C daily)
    with the 8 h duty cycle each, then the validation cycle at 20 °C. Sessions are separated by ``rest_hours``
    with the spindle stopped while the room moves linearly to the next session's starting temperature."""
    sessions = [("ambient_20C", constant(20.0)), ("warm_ventilation", warm_ventilation()),
                ("ambient_17_27C", daily_cycle(17.0, 27.0, start_hour=8.0)), ("validation", constant(20.0))]
    prog: list[Block] = []
    pieces: list[tuple[float, Profile | None]] = []
    for i, (label, amb) in enumerate(sessions):
        duty = s1_validation if label == "validation" else s1_duty
        part = duty(dt_s, condition=label)
        prog += [Block(h, n, p, condition=label) for h, n, p in _runs(part)]
        pieces.append((part.hours, amb))
        if i < len(sessions) - 1:
            prog.append(Block(rest_hours, condition=label))
            pieces.append((rest_hours, None))
    return blocks(prog, dt_s, ambient=sequence(pieces), name="s1_conditions")


def _runs(scenario: Scenario) -> list[tuple[float, float, float]]:
    """(hours, speed, cutting power) of each constant run of a block scenario."""
    f = scenario.frame
    key = f["speed_rpm"].astype(str) + "/" + f["cutting_power_W"].astype(str)
    starts = np.flatnonzero(np.r_[True, key.to_numpy()[1:] != key.to_numpy()[:-1]])
    t = np.r_[scenario.time_s[starts], scenario.time_s[-1]]
    return [(float(t[i + 1] - t[i]) / 3600.0, float(f["speed_rpm"].iloc[s]), float(f["cutting_power_W"].iloc[s]))
            for i, s in enumerate(starts)]


def sequence(pieces: Sequence[tuple[float, Profile | None]]) -> Profile:
    """Profiles one after another, each for its hours on its own clock; None ramps linearly between neighbours."""
    ends = np.cumsum([h * 3600.0 for h, _ in pieces])
    starts = np.r_[0.0, ends[:-1]]

    def profile(t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        out = np.empty_like(t)
        for i, (_, prof) in enumerate(pieces):
            last = i == len(pieces) - 1
            mask = (t >= starts[i]) & ((t < ends[i]) | last)
            if prof is not None:
                out[mask] = prof(t[mask] - starts[i])
                continue
            before = pieces[i - 1][1](np.array([ends[i - 1] - starts[i - 1]]))[0] if i else None
            after = pieces[i + 1][1](np.array([0.0]))[0] if not last else None
            a = before if before is not None else after
            b = after if after is not None else a
            out[mask] = a + (b - a) * (t[mask] - starts[i]) / (ends[i] - starts[i])
        return out
    return profile


def s2_warmup(dt_s: float = 1.0, speed_rpm: float = 6000.0, seconds: float = 16_000.0) -> Scenario:
    """Study S2: idle warm-up at constant speed for 16,000 s sampled at 1 s."""
    return blocks([Block(seconds / 3600.0, speed_rpm, condition=f"warmup_{speed_rpm:g}rpm")], dt_s,
                  ambient=constant(21.0), name="s2_warmup")


def s2_speed_steps(dt_s: float = 10.0, speeds_rpm: Sequence[float] = (2000, 4000, 6000, 8000),
                   seconds: float = 16_000.0, rest_hours: float = 4.0) -> Scenario:
    """S2-style idle warm-ups (16,000 s) at several speeds, each followed by a ``rest_hours`` cool-down."""
    prog = [b for n in speeds_rpm for b in (Block(seconds / 3600.0, n), Block(rest_hours))]
    return blocks(prog, dt_s, ambient=daily_cycle(20.0, 22.5, start_hour=8.0), name="s2_speed_steps")


def s3_programme(dt_s: float = 60.0, speeds_rpm: Sequence[float] = (3000, 6000, 9000, 12000),
                 hours_on: float = 10.0, hours_off: float = 9.5) -> Scenario:
    """Study S3-like motorized-spindle run: 4 speed plateaus with stops (≈ 78 h at 1 min: 4,682 samples),
    daily ambient 18–24 °C and an on/off chiller (20 °C ± 0.5 K, ≈ 20 min period)."""
    prog = [Block(1 / 60)] + [b for n in speeds_rpm for b in (Block(hours_on, n), Block(hours_off))]
    return blocks(prog, dt_s, ambient=daily_cycle(18.0, 24.0, start_hour=7.0), coolant=chiller_cycling(20.0, 0.5),
                  name="s3_programme")


def demo(dt_s: float = 30.0) -> Scenario:
    """Small demonstration: 1500/3000/4500/6000 rpm for 2 h each with 1.5 h cool-downs (14 h), 20–22 °C day."""
    prog = [b for n in (1500, 3000, 4500, 6000) for b in (Block(2.0, n), Block(1.5))]
    return blocks(prog, dt_s, ambient=daily_cycle(20.0, 22.0, start_hour=7.0), name="demo")


SCENARIOS: dict[str, Callable[..., Scenario]] = {
    "demo": demo,
    "fl_thermal": fl_thermal,
    "iso230_3_constant_speed": iso230_3_constant_speed,
    "iso230_3_speed_spectrum": iso230_3_speed_spectrum,
    "iso230_3_environmental": iso230_3_environmental,
    "s1_duty": s1_duty,
    "s1_validation": s1_validation,
    "s1_conditions": s1_conditions,
    "s2_warmup": s2_warmup,
    "s2_speed_steps": s2_speed_steps,
    "s3_programme": s3_programme,
}


def build(name: str, **kwargs) -> Scenario:
    """The named scenario of :data:`SCENARIOS` built with ``kwargs`` (e.g. ``dt_s``)."""
    if name not in SCENARIOS:
        raise InputError(f"unknown scenario {name!r}", hint=f"known: {', '.join(SCENARIOS)}")
    return SCENARIOS[name](**kwargs)
