import numpy as np
import pandas as pd
import pytest

from thermodrift.core.metrics import NAMES, channel_metrics, evaluate


def test_perfect_prediction():
    y = np.array([0.0, 5.0, 12.0, 20.0])
    m = channel_metrics(y, y)
    assert m["rmse"] == 0 and m["max_abs_error"] == 0 and m["r2"] == 1 and m["compensation_rate"] == 1
    assert m["vaf"] == pytest.approx(100.0)


def test_known_values_in_um():
    y = np.array([10.0, 20.0, 30.0, 40.0])
    p = np.array([12.0, 18.0, 33.0, 40.0])  # residuals -2, 2, -3, 0 µm
    m = channel_metrics(y, p)
    assert m["mse"] == pytest.approx((4 + 4 + 9) / 4)
    assert m["rmse"] == pytest.approx(np.sqrt(17 / 4))
    assert m["mae"] == pytest.approx(7 / 4)
    assert m["max_abs_error"] == pytest.approx(3.0)
    assert m["mean_error"] == pytest.approx(-3 / 4)
    assert m["r2"] == pytest.approx(1 - 17 / 500)
    assert m["relative_error_pct"] == pytest.approx(100 * (7 / 4) / 25)
    assert m["compensation_rate"] == pytest.approx(1 - 3 / 40)
    # explained variance ignores a constant bias, R² does not
    biased = channel_metrics(y, y + 5.0)
    assert biased["explained_variance"] == pytest.approx(1.0) and biased["r2"] < 1.0


def test_evaluate_per_channel_and_mean():
    y = pd.DataFrame({"z_um": [1.0, 2.0, 3.0], "x_um": [0.0, 1.0, 0.0]})
    pred = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    out = evaluate(y, pred)
    assert set(out) == {"z_um", "x_um", "mean"}
    assert set(out["mean"]) == set(NAMES)
    assert out["z_um"]["rmse"] == 0
    assert out["mean"]["rmse"] == pytest.approx(out["x_um"]["rmse"] / 2)


def test_shape_mismatch_is_an_error():
    with pytest.raises(ValueError):
        channel_metrics(np.zeros(3), np.zeros(4))
