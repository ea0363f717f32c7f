"""Simulated reference machines: recordings that round-trip, carry working conditions and are reproducible."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from thermodrift.core import registry
from thermodrift.core.cli import main
from thermodrift.core.recording import TEMPERATURE_ROLES, detect_conditions, load_recording
from thermodrift.plugins.datasets.reference_machines import MACHINES

EXPECTED = {  # name: (temperature-like channels, displacement channels, rows)
    "demo_spindle": (5, 2, 1681),
    "turning_centre_s1": (19, 2, 3562),  # radial error at two positions along Z
    "vmc_spindle_s2": (16, 1, 12161),
    "motorized_spindle_s3": (16, 1, 4682),
}


@pytest.fixture(scope="module")
def recordings():
    return {name: MACHINES[name](seed=0) for name in EXPECTED}


def test_machines_are_registered_datasets():
    reg = registry.load()
    assert set(EXPECTED) <= set(reg.names("dataset"))
    rec = reg.create("dataset", "demo_spindle", seed=1, hours=3.0)
    assert rec.duration_s == pytest.approx(3 * 3600)


@pytest.mark.parametrize("name", list(EXPECTED))
def test_recording_round_trips_and_has_four_conditions(recordings, tmp_path, name):
    rec = recordings[name]
    n_temp, n_disp, rows = EXPECTED[name]
    assert len(rec) == rows
    assert sum(len(rec.columns(r)) for r in TEMPERATURE_ROLES) == n_temp
    assert len(rec.displacements.columns) == n_disp
    assert rec.conditions().nunique() >= 4
    span = rec.displacements.max() - rec.displacements.min()
    assert (span > 10).all() and (span < 200).all(), "drift of tens of µm"
    rec.write(tmp_path / "r.csv", tmp_path / "r.yaml")
    back = load_recording(tmp_path / "r.csv", tmp_path / "r.yaml")
    assert main(["validate", str(tmp_path / "r.csv"), "--manifest", str(tmp_path / "r.yaml")]) == 0
    assert list(back.data.columns) == list(rec.data.columns)
    assert {c: (ch.role, ch.unit) for c, ch in back.channels.items()} == \
        {c: (ch.role, ch.unit) for c, ch in rec.channels.items()}
    numeric = [c for c in rec.data.columns if rec.channels[c].role != "condition"]
    np.testing.assert_allclose(back.data[numeric].to_numpy(), rec.data[numeric].to_numpy(), rtol=1e-12)
    assert (back.conditions().to_numpy() == rec.conditions().to_numpy()).all()


def test_speed_programmes_are_detected_as_conditions_too(recordings):
    for name in ("demo_spindle", "vmc_spindle_s2", "motorized_spindle_s3"):
        rec = recordings[name]
        labels = detect_conditions(rec.time_s, rec.speed.to_numpy())
        assert len(set(labels) - {"c00_idle"}) >= 4, name


def test_realistic_sensor_errors(recordings):
    rec = recordings["demo_spindle"]
    synthetic = MACHINES["demo_spindle"].generate(seed=0)
    truth_T = synthetic.result.temperatures["column"]
    error = rec.data["T_column"] - truth_T
    offset = synthetic.truth["sensor_offsets_K"]["T_column"]
    assert error.mean() == pytest.approx(offset, abs=0.005)  # a fixed offset within Pt100 class A …
    assert abs(offset) <= 0.15 + 0.002 * 25 + 0.15       # … of the spec value plus the class tolerance
    assert 0.005 < error.std() < 0.02                       # … plus white noise
    steps = np.diff(np.sort(np.unique(rec.data["T_column"].round(6))))
    assert steps.min() == pytest.approx(0.01, abs=1e-6)     # quantized to 0.01 K
    z_noise = (rec.data["disp_z"] - synthetic.result.displacements["z"]).std()
    assert 0.03 < z_noise < 0.07


def test_same_seed_same_recording_other_seed_other_noise():
    a, b, c = MACHINES["motorized_spindle_s3"](seed=5, hours=6), MACHINES["motorized_spindle_s3"](seed=5, hours=6), \
        MACHINES["motorized_spindle_s3"](seed=6, hours=6)
    pd.testing.assert_frame_equal(a.data, b.data)
    assert not np.allclose(a.data["T0"], c.data["T0"])


def test_simulate_verb_writes_table_manifest_and_truth(tmp_path, capsys):
    code = main(["simulate", "--machine", "demo_spindle", "--seed", "2", "--hours", "4", "--out", str(tmp_path),
                 "--mechanism", "slow_structural_mode:tau_h=6", "--no-progress"])
    assert code == 0
    table, manifest = tmp_path / "demo_spindle_seed2.csv", tmp_path / "demo_spindle_seed2.manifest.yaml"
    rec = load_recording(table, manifest)
    assert rec.duration_s == pytest.approx(4 * 3600)
    truth = json.loads((tmp_path / "demo_spindle_seed2.truth.json").read_text())
    assert truth["seed"] == 2 and truth["machine"] == "demo_spindle"
    assert truth["mechanisms"][-1] == {"id": "slow_structural_mode",
                                       "params": {"tau_h": 6.0, "gain_um_K": -2.0, "G_W_K": 4.0},
                                       "options": {"nodes": None, "groups": ["structure", "housing"], "axes": ["z"],
                                                   "ambient_W_K": 2.0}}
    assert "slow_structure" in truth["network"]["nodes"]
    assert set(truth["sensor_offsets_K"]) == {"T_front_bearing", "T_rear_bearing", "T_housing", "T_column",
                                              "T_ambient"}
    assert main(["simulate", "--machine", "no_such", "--out", str(tmp_path)]) == 2
    assert "unknown dataset" in capsys.readouterr().err


def test_scenario_from_recording_reproduces_the_programme(recordings):
    from thermodrift.core import physics

    rec = recordings["motorized_spindle_s3"]
    scen = physics.Scenario.from_recording(rec)
    synthetic = MACHINES["motorized_spindle_s3"].generate(seed=0)
    original = synthetic.result.scenario.frame
    np.testing.assert_array_equal(scen.frame["speed_rpm"].to_numpy(), original["speed_rpm"].to_numpy())
    # measured ambient and coolant inlet (offset, lag, noise) stand in for the true boundaries
    assert np.abs(scen.frame["ambient_degC"] - original["ambient_degC"]).max() < 0.5
    assert np.abs(scen.frame["coolant_inlet_degC"] - original["coolant_inlet_degC"]).max() < 0.5
    resim = physics.simulate(synthetic.result.network, scen)
    assert np.abs(resim.displacements["z"] - synthetic.result.displacements["z"]).max() < 2.0
