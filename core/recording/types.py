"""The Recording type: channels by role in canonical units, indexed by time in s.

Canonical units in :attr:`Recording.data`: temperatures (the roles in :data:`TEMPERATURE_ROLES`) in °C,
displacement in µm, speed in rpm, cutting_power in W, axis_velocity in mm/min, solar_irradiance in W/m², heating
in W (or unitless, "1", when the manifest gives no power unit); condition is a label.

A model's target is a displacement (µm) or a temperature (°C; its errors in K): :data:`TARGET_ROLES`, with the unit
its errors are stated in (:data:`ERROR_UNITS`, :meth:`Recording.error_unit`). A target is never an input.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import pandas as pd
import yaml

from thermodrift.core.errors import InputError
from thermodrift.core.recording.conditions import detect_conditions

ROLES = ("speed", "temperature", "displacement", "ambient", "coolant_inlet", "coolant_outlet",
         "cutting_power", "axis_velocity", "solar_irradiance", "heating", "condition", "ignore")
TEMPERATURE_ROLES = ("temperature", "ambient", "coolant_inlet", "coolant_outlet")
# Heat inputs of a building (W/m², W or a unitless heating signal): inputs a model reads like temperatures.
HEAT_INPUT_ROLES = ("solar_irradiance", "heating")
# The channels a model reads and a selector picks from: every temperature (°C) and the heat inputs.
INPUT_ROLES = (*TEMPERATURE_ROLES, *HEAT_INPUT_ROLES)
# Roles a model may predict, and the unit of an error (a difference) in each: a temperature error is in K.
TARGET_ROLES = ("displacement", "temperature")
ERROR_UNITS = {"displacement": "µm", "temperature": "K"}
TIME_INDEX = "time_s"
RUN_COLUMN = "run"  # the run column :meth:`Recording.write` adds for a recording of several runs


@dataclass(frozen=True)
class Channel:
    """One column of a recording: its role, its canonical unit (None for labels) and free metadata."""

    name: str
    role: str
    unit: str | None
    meta: dict[str, Any] = field(default_factory=dict)


class Recording:
    """A time series of channels by role, indexed by time in s, in canonical units.

    ``data`` holds exactly the columns named by ``channels``; its index is time in s (float, named
    ``time_s``) starting where the table starts. ``notes`` records what loading did silently (ignored
    columns, interpolated samples, irregular sampling). ``runs``: one label per row naming the independent
    recording (run) the row belongs to, each run one contiguous block of rows (None: one run); a model with
    history starts each run afresh (:meth:`run_starts_s`).
    """

    def __init__(self, data: pd.DataFrame, channels: dict[str, Channel], source: str = "<memory>",
                 notes: Iterable[str] | None = None, runs: Iterable[Any] | None = None):
        missing = [name for name in channels if name not in data.columns]
        extra = [str(col) for col in data.columns if col not in channels]
        if missing or extra:
            raise ValueError(f"data and channels disagree: channels without data {missing}, "
                             f"data without channel {extra}")
        for name, ch in channels.items():
            if ch.name != name:
                raise ValueError(f"channel {ch.name!r} is filed under the name {name!r}")
            if ch.role not in ROLES or ch.role == "ignore":
                raise ValueError(f"channel {name!r} has role {ch.role!r}; use one of {', '.join(ROLES[:-1])}")
        if TIME_INDEX in channels:
            raise ValueError(f"{TIME_INDEX!r} is the time index and cannot be a channel name")
        self.data = data.set_axis(pd.Index(np.asarray(data.index, dtype=float), name=TIME_INDEX), axis=0)
        self.channels = dict(channels)
        self.source = source
        self.notes: list[str] = list(notes or [])
        self._labels: pd.Series | None = None
        self._runs: np.ndarray | None = None
        if runs is not None:
            labels = np.array([str(r) for r in runs], dtype=object)
            if len(labels) != len(self.data):
                raise ValueError(f"{len(labels)} run labels for {len(self.data)} rows")
            starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]]) if len(labels) else np.array([], int)
            if len(set(labels[starts])) != len(starts):
                raise ValueError("each run must be one contiguous block of rows")
            self._runs = labels if len(starts) > 1 else None

    def __len__(self) -> int:
        return len(self.data)

    def __repr__(self) -> str:
        roles = ", ".join(f"{len(self.columns(r))} {r}" for r in ROLES if self.columns(r))
        return f"Recording({len(self)} rows, {self.duration_s / 3600:.2f} h, {roles}, source={self.source!r})"

    @property
    def time_s(self) -> np.ndarray:
        """Sample times in s."""
        return self.data.index.to_numpy()

    @property
    def duration_s(self) -> float:
        """Last minus first sample time in s."""
        t = self.time_s
        return float(t[-1] - t[0]) if len(t) else 0.0

    @property
    def sampling_interval_s(self) -> float:
        """Median sampling interval in s (nan for fewer than two rows)."""
        return float(np.median(np.diff(self.time_s))) if len(self) > 1 else float("nan")

    @property
    def is_regular(self) -> bool:
        """True when every interval is within 1 % of the median interval."""
        dt = np.diff(self.time_s)
        return bool(len(dt)) and bool(np.all(np.abs(dt - np.median(dt)) <= 0.01 * np.median(dt)))

    def columns(self, role: str) -> list[str]:
        """Names of the channels with ``role``, in table order."""
        if role not in ROLES:
            raise ValueError(f"unknown role {role!r}; use one of {', '.join(ROLES)}")
        return [str(c) for c in self.data.columns if self.channels[c].role == role]

    def frame(self, role: str) -> pd.DataFrame:
        """The channels with ``role`` as a DataFrame indexed by time in s."""
        return self.data[self.columns(role)]

    @property
    def temperatures(self) -> pd.DataFrame:
        """Temperature channels in °C (ambient and coolant are separate roles)."""
        return self.frame("temperature")

    @property
    def displacements(self) -> pd.DataFrame:
        """Displacement (drift) channels in µm."""
        return self.frame("displacement")

    @property
    def speed(self) -> pd.Series | None:
        """Spindle speed in rpm, or None."""
        cols = self.columns("speed")
        return self.data[cols[0]] if cols else None

    def error_unit(self, targets: Iterable[str]) -> str:
        """The unit in which errors of ``targets`` are stated: µm for displacements, K for temperatures
        (``"µm, K"`` for a mix, in target order)."""
        units = [ERROR_UNITS.get(self.channels[t].role, str(self.channels[t].unit)) for t in targets]
        return ", ".join(dict.fromkeys(units)) or ERROR_UNITS["displacement"]

    def conditions(self) -> pd.Series:
        """Working-condition label per sample: the condition channel, else detected from the speed schedule.

        Detection (:func:`detect_conditions`): a new condition starts at each change to another nonzero speed
        level; a stop joins the condition before it; leading idle time is ``c00_idle``. Labels look like
        ``c01_1250rpm``. Without speed or condition channel every sample is ``c01_all``. With several runs and
        no condition channel, conditions are detected within each run and named ``<run>/<label>`` (without
        speed: the run's name).
        """
        if self._labels is None:
            cond = self.columns("condition")
            if cond:
                labels = self.data[cond[0]].astype(str).to_numpy()
            elif self._runs is not None:  # several runs: conditions detected within each, named after it
                labels = np.empty(len(self), dtype=object)
                for run in self.run_names:
                    rows = self._runs == run
                    inner = (detect_conditions(self.time_s[rows], self.speed.to_numpy()[rows])
                             if self.speed is not None else np.full(int(rows.sum()), "", dtype=object))
                    labels[rows] = [f"{run}/{lab}" if lab else run for lab in inner]
            elif self.speed is not None:
                labels = detect_conditions(self.time_s, self.speed.to_numpy())
            else:
                labels = np.full(len(self), "c01_all", dtype=object)
            self._labels = pd.Series(labels, index=self.data.index, name="condition", dtype=object)
        return self._labels

    def condition_spans(self) -> pd.DataFrame:
        """One row per contiguous run of a condition: ``label``, ``start_s`` and ``end_s`` (half-open).

        ``end_s`` is the start of the next run, or the last time plus one sampling interval.
        """
        labels = self.conditions().to_numpy()
        t = self.time_s
        if not len(t):
            return pd.DataFrame({"label": [], "start_s": [], "end_s": []})
        starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
        step = self.sampling_interval_s if len(t) > 1 else 0.0
        ends = np.r_[t[starts[1:]], t[-1] + step]
        return pd.DataFrame({"label": labels[starts], "start_s": t[starts], "end_s": ends})

    def runs(self) -> pd.Series:
        """Run label per sample: the independent recordings (files, sheets or a run column) in time order;
        ``run1`` for every sample of a single recording."""
        labels = self._runs if self._runs is not None else np.full(len(self), "run1", dtype=object)
        return pd.Series(labels, index=self.data.index, name="run", dtype=object)

    @property
    def run_names(self) -> list[str]:
        """The run labels in time order."""
        return [str(r) for r in dict.fromkeys(self.runs().to_numpy())]

    @property
    def run_starts_s(self) -> list[float]:
        """Times (s) at which the second and later runs start; empty for a single run. Models with history
        read them (``X.attrs["run_starts_s"]``) and start each run from its own first rows."""
        if self._runs is None:
            return []
        labels = self._runs
        return [float(t) for t in self.time_s[1:][labels[1:] != labels[:-1]]]

    def select(self, rows: Any) -> Recording:
        """The recording restricted to ``rows`` (boolean mask or positions); condition labels are kept."""
        mask = np.asarray(rows)
        if mask.dtype == bool and len(mask) != len(self):
            raise ValueError(f"boolean mask has {len(mask)} entries for {len(self)} rows")
        positions = np.flatnonzero(mask) if mask.dtype == bool else mask.astype(int)
        runs = None if self._runs is None else self._runs[positions]
        sub = Recording(self.data.iloc[positions], self.channels, self.source, self.notes, runs=runs)
        sub._labels = self.conditions().iloc[positions]
        return sub

    def write(self, table_path: str | os.PathLike, manifest_path: str | os.PathLike) -> None:
        """Write the table (CSV, Parquet or XLSX by suffix; time column ``time_s``) and its manifest (YAML)."""
        table = Path(table_path)
        frame = self.data.reset_index()
        if self._runs is not None:
            frame[RUN_COLUMN] = self._runs
        suffix = table.suffix.lower()
        if suffix == ".csv":
            frame.to_csv(table, index=False)
        elif suffix == ".parquet":
            frame.to_parquet(table, index=False)
        elif suffix == ".xlsx":
            frame.to_excel(table, index=False, sheet_name="data")
        else:
            raise InputError(f"cannot write table type {suffix!r}", file=str(table),
                             hint="use .csv, .parquet or .xlsx")
        channels = {}
        for name in self.data.columns:
            ch = self.channels[name]
            spec = {"role": ch.role} if ch.unit is None else {"role": ch.role, "unit": ch.unit}
            channels[str(name)] = {**spec, **ch.meta}
        manifest = {"time": TIME_INDEX, **({"run": RUN_COLUMN} if self._runs is not None else {}),
                    "channels": channels}
        text = yaml.safe_dump(manifest, allow_unicode=True, sort_keys=False, default_flow_style=None)
        Path(manifest_path).write_text(f"# manifest for {table.name}\n{text}", encoding="utf-8")

    def summary(self) -> str:
        """Multi-line overview: file, rows, duration, sampling, channels by role, working conditions, notes."""
        lines = [f"file: {self.source}", f"rows: {len(self)}"]
        t = self.time_s
        if len(t):
            lines.append(f"duration: {self.duration_s / 3600:.3f} h ({t[0]:g} s to {t[-1]:g} s)")
        if len(t) > 1:
            dt = np.diff(t)
            regular = "regular" if self.is_regular else f"irregular, {dt.min():g} s to {dt.max():g} s"
            lines.append(f"sampling interval: {self.sampling_interval_s:g} s ({regular})")
        lines.append("channels:")
        for role in ROLES:
            cols = self.columns(role) if role != "ignore" else []
            if cols:
                lines.append(f"  {role} ({len(cols)}):")
                lines.extend(f"    {self._describe(c)}" for c in cols)
        source = (f"column {self.columns('condition')[0]!r}" if self.columns("condition")
                  else f"speed {self.columns('speed')[0]!r}" if self.columns("speed") else "no speed channel")
        spans = self.condition_spans()
        lines.append(f"working conditions ({spans['label'].nunique()}, from {source}):")
        width = max((len(str(s)) for s in spans["label"]), default=0)
        lines.extend(f"  {row.label:<{width}}  {row.start_s / 3600:8.3f} h to {row.end_s / 3600:8.3f} h"
                     f"  ({row.start_s:g} s to {row.end_s:g} s)" for row in spans.itertuples())
        if self._runs is not None:
            lines.append(f"runs ({len(self.run_names)}, each starts afresh):")
            runs, width = self.runs().to_numpy(), max(len(r) for r in self.run_names)
            for run in self.run_names:
                t_run = t[runs == run]
                lines.append(f"  {run:<{width}}  {len(t_run):6d} rows  {t_run[0] / 3600:8.3f} h to "
                             f"{t_run[-1] / 3600:8.3f} h")
        if self.notes:
            lines.append("notes:")
            lines.extend(f"  - {note}" for note in self.notes)
        return "\n".join(lines)

    def _describe(self, name: str) -> str:
        ch = self.channels[name]
        meta = "".join(f", {k}={v}" for k, v in ch.meta.items())
        if ch.unit is None:
            values = self.data[name]
            return f"{name}: {values.nunique()} labels{meta}"
        values = self.data[name].to_numpy()
        measured = np.isfinite(values)
        sparse = "" if measured.all() else f", measured in {int(measured.sum())} of {len(values)} rows"
        return f"{name} [{ch.unit}]: {np.nanmin(values):.4g} to {np.nanmax(values):.4g}{meta}{sparse}"

