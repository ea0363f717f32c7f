"""Controller formats: the values a CNC accepts, in the units and step limits its documentation fixes.

- ``csv``: ``time_s``, then per target ``<target>_um`` (written), ``<target>_raw_um`` (the model's prediction),
  ``<target>_status``; a temperature target (its ``axes`` entry has ``unit: degC``) writes ``<target>_degC`` and
  ``<target>_raw_degC`` instead. The CNC formats below take displacement targets only.
- ``siemens`` (SINUMERIK 840D sl temperature compensation; Function Manual Extended Functions, K3
  Compensations, §4.2 Temperature compensation, 6FC5397-1BP40-3BA1, 03/2013): per axis the setting data
  SD43900 ``$SA_TEMP_COMP_ABS_VALUE`` (position-independent value K0, mm), SD43910 ``$SA_TEMP_COMP_SLOPE``
  (tan β of the position-dependent part, dimensionless: the manual writes tan β(T) = … · 10⁻⁶ from a
  coefficient in µm/m) and SD43920 ``$SA_TEMP_COMP_REF_POSITION`` (P0, mm; the manual's example sets 320 for
  320 mm). The NC limits how fast the total compensation may change per interpolation cycle to
  MD32760 ``$MA_COMP_ADD_VELO_FACTOR`` × MD32000 ``$MA_MAX_AX_VELO``; a larger change is written as several
  rows one interpolation cycle apart, each within that limit over the axis's positions.
- ``fanuc`` (thermal growth compensation: Series 15i/150i-MA Connection Manual (Function) B-63323EN-1/03,
  §1 "thermal growth compensation along tool vector"): absolute values in detection units (1 µm on IS-B
  metric machines; ``detection_unit_um``); "the amount of the compensation, 9999 or more (−9999 or less) by
  using the detection unit, cannot be output once for an axis", so a change of 9999 units or more is written
  as several rows of at most 9998 units each.
- ``beckhoff`` (TwinCAT CNC TF5200 axis compensation, temperature compensation, parameters P-AXIS-00272
  ``temp_comp_position_0``, P-AXIS-00273 ``temp_comp_offset_0`` in 0.1 µm and P-AXIS-00274
  ``temp_comp_coefficient`` in µm/m; infosys.beckhoff.com tccncaxisparameter/15266957451): per axis the offset
  at the basic position (integer 0.1 µm), the basic position (0.1 µm) and the coefficient (integer µm/m).

The slope needs two or more positions along an axis (targets with the same ``axis`` and a ``position_mm``);
:func:`axis_line` fits the line per row, as ``thermodrift.core.compensation.cnc_table`` does for a recording.
An axis with one position gets its value as the offset and a slope of 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from thermodrift.compensator.guard import STATUSES, Step

FORMATS = ("csv", "siemens", "fanuc", "beckhoff")
FANUC_MAX_UNITS = 9998  # the documented limit is a change below 9999 detection units per output


def axis_line(values_um: np.ndarray, positions_mm: np.ndarray, reference_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares line through values (n, k) (µm) at k positions (mm) along an axis: K0 at ``reference_mm``
    (µm) and tan β (µm/mm) per row; with one position K0 is the value and tan β NaN."""
    v = np.asarray(values_um, dtype=float)
    v = v.reshape(1, -1) if v.ndim == 1 else v
    p = np.asarray(positions_mm, dtype=float) - reference_mm
    if v.shape[1] != len(p):
        raise ValueError(f"{v.shape[1]} predicted channels for {len(p)} positions")
    if len(p) >= 2:
        A = np.column_stack([np.ones_like(p), p])
        coef, *_ = np.linalg.lstsq(A, v.T, rcond=None)  # (2, n): K0, tan β per row
        return coef[0], coef[1]
    return v[:, 0], np.full(len(v), np.nan)


@dataclass
class Axis:
    name: str
    targets: list[int]  # indices into the package's targets
    positions_mm: np.ndarray


def axes_of(package) -> list[Axis]:
    """Targets grouped by their ``axis``; an axis uses a line only where every target on it has a position."""
    groups: dict[str, list[int]] = {}
    for i, t in enumerate(package.targets):
        groups.setdefault(str(package.axes.get(t, {}).get("axis") or t), []).append(i)
    out = []
    for name, idx in groups.items():
        pos = [package.axes.get(package.targets[i], {}).get("position_mm") for i in idx]
        if len(idx) >= 2 and all(p is not None for p in pos):
            out.append(Axis(name, idx, np.asarray(pos, dtype=float)))
        else:  # no line without positions: one axis entry per target
            out += [Axis(name if len(idx) == 1 else f"{name}:{package.targets[i]}", [i], np.zeros(1)) for i in idx]
    return out


class Writer:
    """Turns each :class:`~thermodrift.compensator.guard.Step` into the rows of one format."""

    def __init__(self, package, fmt: str = "csv", reference_mm: float = 0.0, detection_unit_um: float = 1.0,
                 max_axis_velo_mm_min: float = 10000.0, velo_factor: float = 0.01, ipo_cycle_s: float = 0.004):
        if fmt not in FORMATS:
            raise ValueError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
        self.fmt, self.package = fmt, package
        self.targets = package.targets
        self.units = [str(package.axes.get(t, {}).get("unit", "um")) for t in self.targets]
        if fmt != "csv" and any(u != "um" for u in self.units):
            other = next(t for t, u in zip(self.targets, self.units) if u != "um")
            raise ValueError(f"format {fmt!r} writes displacements; target {other!r} is a temperature: use csv")
        self.axes = axes_of(package)
        self.reference_mm = float(reference_mm)
        self.unit_um = float(detection_unit_um)
        # MD32760 × MD32000 per interpolation cycle (µm per cycle)
        self.siemens_step_um = velo_factor * max_axis_velo_mm_min / 60.0 * ipo_cycle_s * 1000.0
        self.ipo_cycle_s = ipo_cycle_s
        self.last: dict[str, Any] = {}

    def header(self) -> list[str]:
        if self.fmt == "csv":
            return ["time_s"] + [f"{t}_{s}" for t, u in zip(self.targets, self.units)
                                 for s in (u, f"raw_{u}", "status")]
        if self.fmt == "fanuc":
            return ["time_s"] + [f"{t}_units" for t in self.targets] + [f"{t}_status" for t in self.targets]
        if self.fmt == "siemens":
            cols = ["SD43900_TEMP_COMP_ABS_VALUE_mm", "SD43910_TEMP_COMP_SLOPE", "SD43920_TEMP_COMP_REF_POSITION_mm"]
        else:
            cols = ["temp_comp_offset_0_0.1um", "temp_comp_position_0_0.1um", "temp_comp_coefficient_um_per_m"]
        return ["time_s"] + [f"{a.name}.{c}" for a in self.axes for c in cols] + [f"{a.name}_status" for a in self.axes]

    def rows(self, step: Step) -> list[list[Any]]:
        status = [STATUSES[s] for s in step.status]
        if self.fmt == "csv":
            return [[_num(step.time_s)] + [x for i in range(len(self.targets))
                                           for x in (_num(step.written[i]), _num(step.raw[i]), status[i])]]
        if self.fmt == "fanuc":
            return self._fanuc(step, status)
        lines = [self._line(a, step.written) for a in self.axes]
        ax_status = [max((step.status[i] for i in a.targets)) for a in self.axes]
        return self._siemens(step, lines, ax_status) if self.fmt == "siemens" else [
            [_num(step.time_s)] + [v for (k0, slope) in lines for v in (
                int(round(k0 * 10.0)), int(round(self.reference_mm * 1e4)), int(round(slope * 1e3)))]
            + [STATUSES[s] for s in ax_status]]

    def _line(self, axis: Axis, written: np.ndarray) -> tuple[float, float]:
        """(K0 µm at the reference position, tan β µm/mm) of one axis."""
        if len(axis.targets) == 1:
            return float(written[axis.targets[0]]), 0.0
        k0, slope = axis_line(written[axis.targets], axis.positions_mm, self.reference_mm)
        return float(k0[0]), float(slope[0])

    def _fanuc(self, step: Step, status: list[str]) -> list[list[Any]]:
        units = np.round(step.written / self.unit_um).astype(np.int64)
        prev = self.last.get("fanuc", units)
        self.last["fanuc"] = units
        n = max(1, int(math.ceil(np.max(np.abs(units - prev)) / FANUC_MAX_UNITS))) if len(units) else 1
        return [[_num(step.time_s)] + [int(v) for v in np.round(prev + (units - prev) * k / n).astype(np.int64)]
                + status for k in range(1, n + 1)]

    def _siemens(self, step: Step, lines: list[tuple[float, float]], ax_status) -> list[list[Any]]:
        """Rows one interpolation cycle apart so that the change at every position of every axis stays within
        the MD32760 limit."""
        now = np.array(lines)  # (axes, 2): K0 µm, tan β µm/mm
        prev = self.last.get("siemens", now)
        self.last["siemens"] = now
        worst = 0.0
        for a, (d0, ds) in zip(self.axes, now - prev):
            reach = np.abs(a.positions_mm - self.reference_mm).max() if len(a.targets) > 1 else 0.0
            worst = max(worst, abs(d0) + abs(ds) * reach)
        n = max(1, int(math.ceil(worst / self.siemens_step_um))) if worst > 0 else 1
        rows = []
        for k in range(1, n + 1):
            cur = prev + (now - prev) * k / n
            rows.append([_num(step.time_s + (k - n) * self.ipo_cycle_s)]
                        + [v for k0, slope in cur for v in (_num(k0 / 1000.0), _num(slope / 1000.0),
                                                             _num(self.reference_mm))]
                        + [STATUSES[s] for s in ax_status])
        return rows


def _num(v: float) -> str:
    """Shortest text that reads back as the same float (so a replay compares to 1e-9 µm and better)."""
    return repr(float(v)) if np.isfinite(v) else "nan"
