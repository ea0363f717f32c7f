"""What every controller format shares: targets grouped into axes, the line through an axis's positions, and the
settings a format may use.

The slope needs two or more positions along an axis (targets with the same ``axis`` and a ``position_mm``);
:func:`axis_line` fits the line per row, as ``thermodrift.core.compensation.cnc_table`` does for a recording.
An axis with one position gets its value as the offset and a slope of 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from thermodrift.compensator.errors import InputError
from thermodrift.compensator.guard import Step


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


class Format:
    """Turns each :class:`~thermodrift.compensator.guard.Step` into the rows of one controller format.

    A subclass writes ``header()`` (column names; the first is the time in s) and ``rows(step)`` (one or more
    rows of the header's length per update). Every format receives the same settings and uses those it needs:
    ``reference_mm`` (reference position P0 of an axis line, mm), ``detection_unit_um`` (µm),
    ``max_axis_velo_mm_min`` (mm/min), ``velo_factor`` (a fraction), ``ipo_cycle_s`` (interpolation cycle, s).
    ``package`` gives ``targets`` and ``axes`` (target -> {"axis", "position_mm", "unit"}; a target without a
    unit is a displacement in µm, ``unit: degC`` a temperature). ``units`` lists the target units a format
    writes (None: any); a package with another is refused with one line.
    """

    units: tuple[str, ...] | None = ("um",)

    def __init__(self, package, reference_mm: float = 0.0, detection_unit_um: float = 1.0,
                 max_axis_velo_mm_min: float = 10000.0, velo_factor: float = 0.01, ipo_cycle_s: float = 0.004):
        self.package = package
        self.targets = list(package.targets)
        self.target_units = [str(package.axes.get(t, {}).get("unit", "um")) for t in self.targets]
        other = [t for t, u in zip(self.targets, self.target_units) if self.units is not None and u not in self.units]
        if other:
            raise InputError(f"format {type(self).__name__.lower()} writes displacements; target {other[0]!r} is a "
                             "temperature: use csv")
        self.axes = axes_of(package)
        self.reference_mm = float(reference_mm)
        self.unit_um = float(detection_unit_um)
        self.max_axis_velo_mm_min = float(max_axis_velo_mm_min)
        self.velo_factor = float(velo_factor)
        self.ipo_cycle_s = float(ipo_cycle_s)
        self.last: dict[str, Any] = {}

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        """Settings for the conformance suite."""
        return [{}, {"reference_mm": 100.0, "detection_unit_um": 0.1}]

    def header(self) -> list[str]:
        raise NotImplementedError

    def rows(self, step: Step) -> list[list[Any]]:
        raise NotImplementedError

    def line(self, axis: Axis, written: np.ndarray) -> tuple[float, float]:
        """(K0 µm at the reference position, tan β µm/mm) of one axis."""
        if len(axis.targets) == 1:
            return float(written[axis.targets[0]]), 0.0
        k0, slope = axis_line(written[axis.targets], axis.positions_mm, self.reference_mm)
        return float(k0[0]), float(slope[0])


def number(v: float) -> str:
    """Shortest text that reads back as the same float (so a replay compares to 1e-9 µm and better)."""
    return repr(float(v)) if np.isfinite(v) else "nan"
