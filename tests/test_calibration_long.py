"""A long recording calibrates like a short one: 1 M samples at 1 s against ~10 k at 15 s (slow: ~1 min)."""

import numpy as np
import pytest

from thermodrift.core.physics import calibration as cal
from thermodrift.core.physics.synthetic import speed_only

def _recording(dt_s: float, repeats: int):
    return speed_only(0, dt_s, repeats).recording


@pytest.mark.slow
def test_a_million_samples_calibrate_as_well_as_ten_thousand():
    short, long = _recording(15.0, 2), _recording(1.0, 14)
    assert len(short) < 11_000 and len(long) > 1_000_000
    a = cal.calibrate(short, hidden_nodes=1, intervals=False)
    b = cal.calibrate(long, hidden_nodes=1, intervals=False)
    assert a.stop == b.stop == "tolerance"
    # the fit grid follows the programme's time scales, not the sampling step
    assert b.grid_step_s == a.grid_step_s and b.fit_samples < 20_000
    assert np.isfinite(b.rmse["dz"]) and b.rmse["dz"] <= 1.5 * a.rmse["dz"], (a.rmse, b.rmse)
    assert b.rmse["dz"] < b.rmse_initial["dz"] or b.rmse["dz"] <= 1.5 * 0.1  # at the noise floor (σ 0.1 µm)
