"""A long recording calibrates like a short one: 1 M samples at 1 s against ~10 k at 15 s (slow: ~1 min)."""

import numpy as np
import pytest

from thermodrift.core import physics
from thermodrift.core.physics import calibration as cal
from thermodrift.core.physics import scenarios
from thermodrift.core.physics.scenarios import Block
from thermodrift.core.physics.synthetic import synthesize

# Speed-driven heat only (inside the auto family): four nodes, one of them unmeasured, Pt100 offsets.
SPEC = {
    "name": "speed_only", "reference_speed_rpm": 5000,
    "nodes": {n: {"capacity_J_K": 1e4} for n in ("front", "rear", "housing", "h")},
    "edges": [{"a": n, "b": "ambient", "G_W_K": g, "kind": "convection"}
              for n, g in (("front", 4.0), ("rear", 6.0), ("housing", 3.0), ("h", 1.5))],
    "sources": {f"q_{n}": {"type": "bearing", "node": n, "viscous_W": q, "viscous_exponent": 1.4}
                for n, q in (("front", 40.0), ("rear", 30.0), ("housing", 10.0), ("h", 6.0))},
    "outputs": {"z": {"axis": "z", "sensitivity_um_K": {"front": 1.0, "housing": 2.0, "h": 3.0}}},
    "sensors": {"T_front": {"node": "front", "noise_K": 0.02, "offset_K": 0.3},
                "T_rear": {"node": "rear", "noise_K": 0.02, "offset_K": -0.2},
                "T_housing": {"node": "housing", "noise_K": 0.02}, "dz": {"output": "z", "noise_um": 0.1}},
}


def _recording(dt_s: float, repeats: int):
    prog = [Block(0.5)] + [b for n in (1250, 2500, 5000, 3500) for b in (Block(3.0, n), Block(2.0))] * repeats
    return synthesize(physics.network_from_dict(SPEC), scenarios.blocks(prog, dt_s), 0).recording


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
