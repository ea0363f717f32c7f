"""Controller formats against their documented units and step limits."""

import numpy as np
import pandas as pd
import pytest

from thermodrift.compensator import cnc
from thermodrift.compensator.guard import Step
from thermodrift.core.compensation import cnc_table


class FakePackage:
    """Two targets on axis z at 0 and 200 mm, one on x without a position."""

    targets = ["z_near", "z_far", "x"]
    axes = {"z_near": {"axis": "z", "position_mm": 0.0}, "z_far": {"axis": "z", "position_mm": 200.0},
            "x": {"axis": "x"}}


def step(t, values, status=(0, 0, 0)):
    v = np.asarray(values, dtype=float)
    return Step(t, v, v, np.asarray(status, dtype=np.int8))


def test_axis_line_is_the_cnc_table_line():
    pred = np.array([[10.0, 30.0], [5.0, -5.0]])  # µm at 0 and 200 mm
    k0, slope = cnc.axis_line(pred, [0.0, 200.0], 100.0)
    assert np.allclose(k0, [20.0, 0.0]) and np.allclose(slope, [0.1, -0.05])
    table = cnc_table(pred, [0.0, 200.0], 100.0, pd.Series([20.0, 21.0], index=[0.0, 15.0], name="T"), "z")
    assert np.allclose(table["K0_um"], k0) and np.allclose(table["tan_beta_um_per_mm"], slope)


def test_csv_columns_and_statuses():
    w = cnc.writer(FakePackage(), "csv")
    assert w.header()[:4] == ["time_s", "z_near_um", "z_near_raw_um", "z_near_status"]
    (row,) = w.rows(step(15.0, [1.5, 2.5, -3.0], (0, 2, 3)))
    assert row[3] == "ok" and row[6] == "clamped" and row[9] == "held"


def test_siemens_writes_mm_and_a_dimensionless_slope_within_md32760():
    # 0.01 × 10000 mm/min over a 4 ms cycle: 6.67 µm per interpolation cycle
    w = cnc.writer(FakePackage(), "siemens", reference_mm=100.0, max_axis_velo_mm_min=10000.0, velo_factor=0.01,
                   ipo_cycle_s=0.004)
    head = w.header()
    assert "z.SD43900_TEMP_COMP_ABS_VALUE_mm" in head and "z.SD43910_TEMP_COMP_SLOPE" in head
    assert "z.SD43920_TEMP_COMP_REF_POSITION_mm" in head
    (first,) = w.rows(step(0.0, [10.0, 30.0, 0.0]))
    col = {h: i for i, h in enumerate(head)}
    assert float(first[col["z.SD43900_TEMP_COMP_ABS_VALUE_mm"]]) == pytest.approx(0.020)  # 20 µm
    assert float(first[col["z.SD43910_TEMP_COMP_SLOPE"]]) == pytest.approx(1e-4)  # 0.1 µm/mm
    assert float(first[col["z.SD43920_TEMP_COMP_REF_POSITION_mm"]]) == 100.0
    rows = w.rows(step(15.0, [40.0, 60.0, 0.0]))  # K0 +30 µm: more than 4 cycles' worth
    k0 = [float(r[col["z.SD43900_TEMP_COMP_ABS_VALUE_mm"]]) * 1000 for r in [first] + rows]
    assert len(rows) == 5 and np.abs(np.diff(k0)).max() <= 6.67 + 1e-9 and k0[-1] == pytest.approx(50.0)
    assert float(rows[-1][0]) == 15.0 and float(rows[0][0]) == pytest.approx(15.0 - 4 * 0.004)


def test_fanuc_writes_detection_units_and_splits_changes_of_9999_or_more():
    w = cnc.writer(FakePackage(), "fanuc", detection_unit_um=1.0)
    (first,) = w.rows(step(0.0, [1.4, -2.6, 0.0]))
    assert first[1:4] == [1, -3, 0] and all(isinstance(v, int) for v in first[1:4])
    rows = w.rows(step(15.0, [25000.0, 0.0, 9999.0]))
    units = np.array([first[1:4]] + [r[1:4] for r in rows])
    assert np.abs(np.diff(units, axis=0)).max() < 9999 and units[-1].tolist() == [25000, 0, 9999]
    (small,) = w.rows(step(30.0, [25010.0, 0.0, 9999.0]))
    assert small[1] == 25010


def test_beckhoff_writes_tenths_of_a_micrometre_and_um_per_m():
    w = cnc.writer(FakePackage(), "beckhoff", reference_mm=100.0)
    head = w.header()
    (row,) = w.rows(step(0.0, [10.0, 30.0, -1.26]))
    col = {h: i for i, h in enumerate(head)}
    assert row[col["z.temp_comp_offset_0_0.1um"]] == 200  # 20 µm
    assert row[col["z.temp_comp_position_0_0.1um"]] == 1_000_000  # 100 mm
    assert row[col["z.temp_comp_coefficient_um_per_m"]] == 100  # 0.1 µm/mm
    assert row[col["x.temp_comp_offset_0_0.1um"]] == -13 and row[col["x.temp_comp_coefficient_um_per_m"]] == 0
