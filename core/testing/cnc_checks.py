"""Contract checks for controller formats (``thermodrift.compensator.cnc.Format``), on a small package of three
targets (two on axis z at 0 and 200 mm, one on x without a position) and a sequence of updates with every status,
a large jump and a held row.

A format must: write a header of unique column names starting with ``time_s``; give one or more rows per update,
each as long as the header, of text or integers, never an empty cell; give the same rows for the same updates;
and, where it writes displacements only, refuse a temperature target with one line.
"""

from __future__ import annotations

import numpy as np

from thermodrift.compensator.errors import InputError
from thermodrift.compensator.guard import Step
from thermodrift.testing.estimator_checks import Factory


class _Package:
    """The smallest thing a format reads: ``targets`` and their ``axes``."""

    def __init__(self, axes: dict[str, dict]):
        self.targets, self.axes = list(axes), axes


AXES = {"z_near": {"axis": "z", "position_mm": 0.0}, "z_far": {"axis": "z", "position_mm": 200.0},
        "x": {"axis": "x"}}
STEPS = [(0.0, [1.5, 2.5, -3.0], [0, 0, 0]), (60.0, [1.9, 2.0, -3.0], [1, 0, 0]),
         (120.0, [250.0, 40.0, 12.0], [2, 2, 2]), (180.0, [250.0, 40.0, 12.0], [3, 3, 3]),
         (240.0, [-1.0, 0.0, 0.5], [4, 0, 0])]


def _rows(factory: Factory, params: dict) -> tuple[list[str], list[list]]:
    fmt = factory(_Package(AXES), **params)
    rows = []
    for t, written, status in STEPS:
        v = np.asarray(written, dtype=float)
        rows += fmt.rows(Step(t, v, v + 0.1, np.asarray(status, dtype=np.int8)))
    return fmt.header(), rows


def check_header_and_rows(factory: Factory, params: dict) -> None:
    """A header of unique names starting with ``time_s``; every row as long as the header, cells text or numbers."""
    header, rows = _rows(factory, params)
    assert header and header[0] == "time_s", f"the header must start with 'time_s', got {header[:1]}"
    assert all(isinstance(h, str) and h for h in header), "every column name is a non-empty string"
    assert len(set(header)) == len(header), f"duplicate column names in {header}"
    assert len(rows) >= len(STEPS), f"{len(rows)} rows for {len(STEPS)} updates"
    for row in rows:
        assert len(row) == len(header), f"a row of {len(row)} cells for {len(header)} columns"
        assert all(isinstance(c, (str, int, float, np.integer, np.floating)) and str(c) != "" for c in row), (
            f"cells must be text or numbers, never empty: {row}")


def check_rows_deterministic(factory: Factory, params: dict) -> None:
    """Two fresh instances write the same rows for the same updates."""
    assert _rows(factory, params) == _rows(factory, params), "the same updates gave different rows"


def check_temperature_targets(factory: Factory, params: dict) -> None:
    """A format that writes displacements only (``units`` not None) refuses a temperature target with one
    InputError; one that takes any unit builds."""
    axes = {**AXES, "T_room": {"unit": "degC"}}
    if getattr(factory, "units", None) is None:
        factory(_Package(axes), **params)
        return
    try:
        factory(_Package(axes), **params)
    except InputError as exc:
        assert "\n" not in str(exc)
        return
    raise AssertionError("a temperature target was accepted by a format that writes displacements (units "
                         f"{factory.units}); refuse it with an InputError")


CNC_CHECKS = (check_header_and_rows, check_rows_deterministic, check_temperature_targets)
