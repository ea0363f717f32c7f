"""Extrapolation: where the rows a model predicts leave the training range of a driver, and by how much.

A driver is an input channel through which heat enters or leaves (:data:`DRIVER_ROLES`): spindle speed (rpm),
cutting power (W), ambient, coolant and every other temperature (°C), heating and solar input. A model has seen
how the drift follows a driver inside the range it was trained on; beyond it, it extrapolates.

The margin is stated on physical grounds, not fitted: a value is outside when it lies beyond the training range
[lo, hi] by more than :func:`margin` = max(share · (hi − lo), the role's floor), the share by role in
:data:`SHARES`, the floors in :data:`FLOORS`.

* Speed: :data:`SPEED_MARGIN` = 10 % of the span. The heat a spindle makes grows with speed as n^p, p from 1.5 to
  :data:`HEAT_EXPONENT` = 2 (bearing friction, windage): 10 % beyond the fastest speed trained is up to 21 % more
  heat than any the model saw.
* Heat and temperatures: the same condition stated in heat, (1 + 10 %)^2 − 1 = 21 % of the span
  (:data:`HEAT_MARGIN`), for heat inputs (cutting power, heating, solar) and for temperatures, whose rises in a
  linear thermal network are proportional to the heat that drives them.
* :data:`FLOORS`: a temperature within 0.5 K of its training range is no new condition: IEC 60751 class B, the
  common industrial Pt100, is accurate to ±(0.3 + 0.005·|T|) K, 0.4 to 0.6 K between 20 and 60 °C. Speed, power
  and heat inputs are read without such an error; their floor is 0.

A level counts only where it was held: :func:`check` compares the drivers' running medians over
:data:`HOLD_S` = 10 min, in the training rows and in the predicted rows each, so a sample or two (the first rows
of the next run that a time cut leaves in the training part, a spike) neither widens a training range nor makes
an excursion. Ten minutes is about the shortest thermal time constant a thermal-error model resolves (bearing
rings, sensor housings): a shorter level heats nothing measurably.

:func:`excursions` compares training and predicted rows; :func:`check` does it for a split of a recording (the
outer held-out part, or one inner fold); :func:`mark` adds to the AutoML leaderboard, per candidate, the drivers it
reads in which an inner fold's validation rows extrapolated (``inner_extrapolated``; empty: never, and
``never_extrapolated`` is true). The compensator stores each input's training range; ``thermodrift compensate``
reports the inputs that leave it by the same margin as they stream (:class:`Watch`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import pandas as pd

from thermodrift.core.recording import HEAT_INPUT_ROLES, INPUT_ROLES, TEMPERATURE_ROLES

DRIVE_ROLES = ("speed", "cutting_power")
DRIVER_ROLES = (*DRIVE_ROLES, *TEMPERATURE_ROLES, *HEAT_INPUT_ROLES)
SPEED_MARGIN = 0.10  # share of the speed span
HEAT_EXPONENT = 2.0  # heat ∝ speed^p, p up to 2
HEAT_MARGIN = (1.0 + SPEED_MARGIN) ** HEAT_EXPONENT - 1.0  # 0.21: the same condition in heat (and temperature rise)
SHARES = {"speed": SPEED_MARGIN, **{role: HEAT_MARGIN for role in DRIVER_ROLES if role != "speed"}}
FLOORS = {role: 0.5 for role in TEMPERATURE_ROLES}  # K: a Pt100 class B's accuracy at 20 to 60 °C
HOLD_S = 600.0  # s: a level counts where its running median over this window holds it
STATED = "margin: 10 % of the span for speed, 21 % for heat and temperatures, 0.5 K at least; levels held 10 min"
_SHOWN_UNITS = {"degC": "K", "W_m2": "W/m²", "1": ""}  # how far beyond is a difference: K for temperatures


@dataclass(frozen=True)
class Excursion:
    """One driver outside its training range [``low``, ``high``]: its farthest ``value``, ``beyond`` (how far past
    the range, in the driver's unit; K for temperatures), ``share`` (``beyond`` over the span; inf for a driver
    that was constant in training) and ``rows`` (how many rows lie beyond the margin)."""

    driver: str
    role: str
    unit: str
    low: float
    high: float
    value: float
    beyond: float
    share: float
    rows: int

    def describe(self) -> str:
        """``spindle reaches 8000 rpm, 6400 rpm above its training range 0 to 1600 rpm (400 % of that span)``."""
        unit = {"degC": "°C", "1": ""}.get(self.unit, self.unit)
        unit = f" {unit}" if unit else ""
        diff = _SHOWN_UNITS.get(self.unit, self.unit)
        diff = f" {diff}" if diff else ""
        side = "above" if self.value > self.high else "below"
        span = f"{self.share:.0%} of that span" if np.isfinite(self.share) else "constant in training"
        return (f"{self.driver} reaches {self.value:.4g}{unit}, {self.beyond:.3g}{diff} {side} its training range "
                f"{self.low:.4g} to {self.high:.4g}{unit} ({span})")


def margin(role: str, low: float, high: float) -> float:
    """How far beyond [``low``, ``high``] a value of ``role`` may lie before it counts as extrapolation."""
    return max(SHARES.get(role, HEAT_MARGIN) * (high - low), FLOORS.get(role, 0.0))


def excursions(train: pd.DataFrame, predicted: pd.DataFrame, roles: dict[str, str],
               units: dict[str, str] | None = None) -> list[Excursion]:
    """The drivers (columns of both frames) whose ``predicted`` rows leave their ``train`` range by more than the
    margin: speed first, then farthest first (by share of the span)."""
    ranges = {c: (float(np.nanmin(train[c])), float(np.nanmax(train[c]))) for c in train.columns
              if c in predicted.columns and len(train)}
    return _beyond(ranges, predicted, roles, units or {})


def _beyond(ranges: dict[str, tuple[float, float]], predicted: pd.DataFrame, roles: dict[str, str],
            units: dict[str, str]) -> list[Excursion]:
    out = []
    for c, (lo, hi) in ranges.items():
        role = roles.get(c, "temperature")
        if role not in DRIVER_ROLES:
            continue
        values = predicted[c].to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        if not len(values):
            continue
        m = margin(role, lo, hi)
        past = np.maximum(values - hi, lo - values)
        rows = int(np.count_nonzero(past > m))
        if not rows:
            continue
        i = int(np.argmax(past))
        span = hi - lo
        out.append(Excursion(str(c), role, units.get(c, ""), lo, hi, float(values[i]), float(past[i]),
                             float(past[i] / span) if span > 0 else float("inf"), rows))
    return sorted(out, key=lambda e: (e.role != "speed", -e.share, e.driver))  # the speed first: the drive


def drivers(recording, targets) -> list[str]:
    """The recording's driver channels, targets left out."""
    return [c for role in DRIVER_ROLES for c in recording.columns(role) if c not in targets]


def check(recording, train: np.ndarray, predicted: np.ndarray, targets) -> list[Excursion]:
    """The drivers of ``recording`` whose ``predicted`` rows leave the range of its ``train`` rows by more than the
    margin (row positions)."""
    cols = drivers(recording, targets)
    data = recording.data[cols]
    roles = {c: recording.channels[c].role for c in cols}
    units = {c: recording.channels[c].unit or "" for c in cols}
    return excursions(held(data.iloc[np.asarray(train)]), held(data.iloc[np.asarray(predicted)]), roles, units)


def held(frame: pd.DataFrame, window_s: float = HOLD_S) -> pd.DataFrame:
    """The running median of each column over ``window_s`` (centred; rows indexed by time in s): the levels held."""
    step = float(np.median(np.diff(np.asarray(frame.index, dtype=float)))) if len(frame) > 1 else window_s
    k = max(1, int(round(window_s / step))) if step > 0 else 1
    k += 1 - k % 2  # odd, so the window centres on its row
    return frame if k == 1 else frame.rolling(k, center=True, min_periods=1).median()


def of_result(result) -> list[str]:
    """One :func:`summary` line per fold of a job result whose held-out rows extrapolate (none when none does)."""
    rec = result.recording
    if rec is None or not hasattr(rec, "channels"):
        return []
    out = []
    for fold in result.folds:
        if fold.train_rows is None:
            continue
        found = check(rec, fold.train_rows, np.searchsorted(rec.time_s, fold.time_s), result.targets)
        if found:
            out.append(summary(found, held_out_part(fold.name)))
    return out


def held_out_part(fold_name: str) -> str:
    """A held-out part as a warning names it: ``the held-out part (8000rpm)`` for the fold ``held out: 8000rpm``
    (the name a split or :func:`thermodrift.core.tracking.held_out` gives), ``the held-out part (last 20% of
    time)`` for a name without that prefix."""
    return f"the held-out part ({fold_name.removeprefix('held out: ')})"


def summary(found: list[Excursion], what: str) -> str:
    """One line: ``<what> extrapolates: <driver> reaches ...; ...`` (at most three drivers named, then a count)."""
    shown = "; ".join(e.describe() for e in found[:3])
    more = f"; and {len(found) - 3} more driver(s)" if len(found) > 3 else ""
    return f"{what} extrapolates beyond the training range ({STATED}): {shown}{more}"


def candidate_drivers(params: dict, recording, targets, registry) -> set[str]:
    """The drivers a pipeline candidate reads: its selectable inputs (every one the selector may pick), the drive
    channels when a feature stage feeds it, and the channels of its inner model's ``extra_input_roles``."""
    roles = set(INPUT_ROLES)
    if params.get("features") is not None:
        roles |= set(DRIVE_ROLES)
    roles |= set(getattr(registry.get("model", params["model"]).factory, "extra_input_roles", ()))
    return {c for c in drivers(recording, targets) if recording.channels[c].role in roles}


def mark(board: pd.DataFrame, recording, folds, targets, registry, outer: list[Excursion] | None = None
         ) -> pd.DataFrame:
    """``board`` with ``inner_extrapolated``: the drivers a candidate reads in which some inner fold's validation
    rows left that fold's training range by more than the margin (only those in which the held-out part does, when
    ``outer`` names any), and ``never_extrapolated``: none did, so its inner score says nothing about predicting
    beyond the training range."""
    per_fold = [{e.driver for e in check(recording, f.train, f.test, targets)} for f in folds]
    seen = set().union(*per_fold) if per_fold else set()
    if outer:
        seen &= {e.driver for e in outer}
    reads: dict[int, set[str]] = {}
    for trial, text in zip(board["trial"], board["params"]):
        params = json.loads(text)
        if "model" in params:
            reads[int(trial)] = candidate_drivers(params, recording, targets, registry)
    column = []
    for trial, text in zip(board["trial"], board["params"]):
        params = json.loads(text)
        read = reads.get(int(trial)) if "model" in params else \
            set().union(*(reads.get(int(n), set()) for n in params.get("members", [])))
        column.append(", ".join(sorted(seen & (read or set()))))
    out = board.copy()
    out["inner_extrapolated"] = column
    out["never_extrapolated"] = [not c for c in column]
    return out


class Watch:
    """Inputs streamed at run time against the training ranges a compensator package stores (``{input: {min,
    max}}``, inputs in ``names`` order): :meth:`update` per row returns the inputs that have just left their range
    by more than the margin for the first time; :meth:`found` the excursions so far, as :func:`excursions` states
    them."""

    def __init__(self, limits: dict[str, dict[str, float]], names: list[str], roles: dict[str, str],
                 units: dict[str, str] | None = None):
        self.names, self.roles, self.units = list(names), dict(roles), dict(units or {})
        self.low = np.array([float(limits[c]["min"]) for c in self.names])
        self.high = np.array([float(limits[c]["max"]) for c in self.names])
        self.drives = np.array([self.roles.get(c, "temperature") in DRIVER_ROLES for c in self.names])
        self.margin = np.array([margin(self.roles.get(c, "temperature"), lo, hi)
                                for c, lo, hi in zip(self.names, self.low, self.high)])
        self.worst = np.zeros(len(self.names))
        self.value = np.full(len(self.names), np.nan)
        self.rows = np.zeros(len(self.names), dtype=int)

    def update(self, values: np.ndarray) -> list[str]:
        past = np.maximum(values - self.high, self.low - values)  # NaN for a missing value: never counted
        out = self.drives & (past > self.margin)
        new = [self.names[i] for i in np.flatnonzero(out & (self.rows == 0))]
        self.rows += out
        farther = out & (past > self.worst)
        self.worst[farther], self.value[farther] = past[farther], values[farther]
        return new

    def found(self) -> list[Excursion]:
        out = []
        for i in np.flatnonzero(self.rows):
            span = self.high[i] - self.low[i]
            c = self.names[i]
            out.append(Excursion(c, self.roles.get(c, "temperature"), self.units.get(c, ""), float(self.low[i]),
                                 float(self.high[i]), float(self.value[i]), float(self.worst[i]),
                                 float(self.worst[i] / span) if span > 0 else float("inf"), int(self.rows[i])))
        return sorted(out, key=lambda e: (e.role != "speed", -e.share, e.driver))
