"""Origin-translation compensation per condition and the CNC temperature-compensation table."""

import numpy as np
import pandas as pd
import pytest

from thermodrift.core.compensation import cnc_table, origin_translation, s1_ambient_evaluation, write_cnc_table


def test_origin_translation_improvement_is_the_share_of_the_peak_removed():
    y = pd.DataFrame({"d": [0.0, 10.0, 20.0, 40.0, 5.0, 50.0]})
    cond = pd.Series(["a", "a", "a", "b", "b", "b"])
    perfect = origin_translation(y, y.to_numpy(), cond)
    assert np.allclose(perfect["improvement %"], 100.0)
    nothing = origin_translation(y, np.zeros((6, 1)), cond)
    assert np.allclose(nothing["improvement %"], 0.0)
    half = origin_translation(y, y.to_numpy() / 2, cond).set_index("condition")
    assert half.loc["b", "compensated max µm"] == pytest.approx(25.0) and half.loc["b", "improvement %"] == 50.0


def test_cnc_table_recovers_offset_and_slope():
    t = pd.Series(np.linspace(20, 30, 7), name="T2", index=np.arange(7) * 60.0)
    k0, slope = 2.0 * (t - 20).to_numpy(), 0.01 * (t - 20).to_numpy()
    positions = [0.0, 150.0, 300.0]
    pred = np.column_stack([k0 + slope * (p - 100.0) for p in positions])
    table = cnc_table(pred, positions, 100.0, t, axis="x")
    assert np.allclose(table["K0_um"], k0) and np.allclose(table["tan_beta_um_per_mm"], slope)


def test_s1_compensation_on_three_ambient_conditions_and_its_cnc_table(tmp_path):
    table, results = s1_ambient_evaluation(model="mlr", selector="correlation_top_k")
    assert set(table["condition"]) >= {"ambient_20C", "warm_ventilation", "ambient_17_27C"}
    assert table["improvement %"].notna().all() and (table["improvement %"] > 0).all()
    fold = results["ambient_20C"]
    positions = {"radial_error": 0.0, "radial_error_z150": 150.0}
    assert list(fold.y_true.columns) == list(positions)
    pred = fold.predictions["model"]
    key = pd.Series(np.asarray(pred[:, 0]), index=fold.time_s, name="predicted")
    cnc = cnc_table(pred, list(positions.values()), 0.0, key, axis="x")
    path = write_cnc_table(cnc, tmp_path / "cnc.csv")
    text = path.read_text()
    assert text.startswith("# CNC temperature-compensation table")
    back = pd.read_csv(path, comment="#")
    assert np.isfinite(back["tan_beta_um_per_mm"]).all() and len(back) == len(pred)
