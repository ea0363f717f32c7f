"""``diagnose --simulation``: the simulation table (read, checked, put on the recording's times), ``simulate
--drive``, and the finder against the user's own simulation on the independent generator's cases."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from thermodrift.core import cli, registry
from thermodrift.core.errors import InputError
from thermodrift.core.physics import load_network
from thermodrift.core.physics.diagnose import against_simulation, simulation_table
from thermodrift.core.physics.mechanisms import Mechanism
from thermodrift.core.recording import load_recording

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from independent.user_sim import make_sim_case  # noqa: E402


@pytest.fixture(scope="module")
def cutting(tmp_path_factory):
    """A recording with cutting heat the user's simulation leaves out (parameters off by 0.2), on disk."""
    gen, sim = make_sim_case(2, "cutting_heat", "fd", 0.2, False)
    folder = tmp_path_factory.mktemp("cutting")
    table, manifest = gen.write(folder)
    sim_path = folder / "sim.csv"
    sim.to_csv(sim_path, index=False)
    return gen, sim, table, manifest, sim_path


def test_a_finer_simulation_is_put_on_the_recordings_times(cutting):
    gen, sim, table, manifest, _ = cutting
    rec = load_recording(table, manifest)
    t = sim["time_s"].to_numpy()
    fine_t = np.arange(t[0], t[-1] + 1e-9, 30.0)
    fine = pd.DataFrame({c: np.interp(fine_t, t, sim[c]) for c in sim.columns if c != "time_s"})
    fine.insert(0, "time_s", fine_t)
    out = simulation_table.align(fine, rec)
    assert np.allclose(out.index, rec.time_s)
    assert np.allclose(out["disp_z_um"], sim["disp_z_um"], atol=1e-9)


@pytest.mark.parametrize("change,message", [
    ("gap", "gap from"), ("late", "covers"), ("outside", "outside the recording"), ("nan", "missing value"),
    ("nodisp", "no displacement channel")])
def test_a_simulation_that_does_not_fit_the_recording_is_one_line(cutting, change, message):
    gen, sim, table, manifest, _ = cutting
    rec = load_recording(table, manifest)
    bad = sim.copy()
    if change == "gap":
        bad = bad.drop(index=[100, 101, 102])
    elif change == "late":
        bad = bad.iloc[5:]
    elif change == "outside":
        bad.loc[len(bad)] = bad.iloc[-1] + 0.0
        bad.loc[len(bad) - 1, "time_s"] = rec.time_s[-1] + 60.0
    elif change == "nan":
        bad.loc[50, "disp_z_um"] = np.nan
    else:
        bad = bad.drop(columns=[c for c in bad if c.startswith("disp_")])
    with pytest.raises(InputError, match=message) as err:
        simulation_table.align(bad, rec)
    assert "\n" not in str(err.value)


def test_the_left_out_cutting_heat_is_named_and_the_cli_writes_the_report(cutting, tmp_path, capsys):
    gen, sim, table, manifest, sim_path = cutting
    out = tmp_path / "dx"
    code = cli.main(["diagnose", str(table), "--manifest", str(manifest), "--simulation", str(sim_path),
                     "--simulation-inputs", "ambient", "coolant_inlet", "--out", str(out)])
    assert code == 0
    doc = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert list(doc)[:5] == ["baseline", "findings", "rejected", "augmented", "verdict"]
    (f,) = doc["findings"]
    assert f["mechanism"] == "cutting_heat"
    assert set(f["ci"]) == set(f["parameters"]) and all(
        np.isfinite(f["ci"][k]).all() and f["ci"][k][0] <= v <= f["ci"][k][1] for k, v in f["parameters"].items())
    assert all(list(w) == ["channel", "start_s", "end_s"] for w in f["where"]) and f["where"]
    ch = gen.drift_channel
    assert doc["augmented"]["heldout_rmse_um"][ch] < 0.7 * doc["baseline"]["heldout_rmse_um"][ch]
    status = {m["mechanism"]: m["status"] for m in doc["adequacy"]["mechanisms"]}
    assert status["ambient_coupling"] == "nested" and status["coolant_coupling"] == "nested"
    assert status["radiation"] == "untestable" and status["cutting_heat"] == "tested"
    # the slow store's lagged speed heat lies within the null's 3 h and 10 h speed-heat lags: nested, not tested
    assert status["slow_structural_mode"] == "nested"
    slow = next(m for m in doc["adequacy"]["mechanisms"] if m["mechanism"] == "slow_structural_mode")
    assert "null's columns" in slow["reason"]
    assert set(status) == set(registry.default().names("mechanism"))
    for name in ("report.md", "residuals.csv", "fit.png"):
        assert (out / name).stat().st_size > 0


def test_a_form_the_null_takes_whole_is_told_from_one_it_does_not():
    from thermodrift.core.physics.diagnose import sim_forms
    t = np.linspace(0.0, 30 * 3600.0, 901)
    r = (np.sin(t / 7000.0) > 0).astype(float)
    inputs = sim_forms.Inputs(t, r, {})
    null = sim_forms.null_design(inputs, inputs.lag(r, 2000.0), [])
    rows = np.ones(len(t), dtype=bool)
    inside = 2.0 * inputs.lag(r ** 1.5, 3600.0) - inputs.lag(r ** 1.5, 900.0)
    assert sim_forms.outside(np.column_stack([null, inside]), null.shape[1], rows) < 1e-6
    square = np.sin(t / 5000.0) ** 2  # no lag of the speed's heat
    assert sim_forms.outside(np.column_stack([null, square]), null.shape[1], rows) > 10 * sim_forms.IN_NULL


def test_a_null_case_names_nothing():
    gen, sim = make_sim_case(501, None, "fd", 0.2, True)
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        rec = load_recording(*gen.write(Path(tmp)))
    d = against_simulation.diagnose_simulation(rec, sim, simulated_inputs=gen.info["simulated_inputs"])
    assert d.findings == []
    assert all(r["reason"] for r in d.rejected)


class _FanHeat(Mechanism):
    """A third-party mechanism: heat that follows the cutting power, declared for the simulation mode only."""

    id = "fan_heat"
    signature = "follows cutting power"
    simulation_form = {"driver": "cutting_power", "taus_s": (600.0, 1800.0, 7200.0), "sign": 1}


def test_a_third_party_mechanism_takes_part_through_its_declared_form(cutting):
    gen, sim, table, manifest, _ = cutting
    reg = registry.load()
    reg.add("mechanism", "fan_heat", _FanHeat)
    rec = load_recording(table, manifest)
    d = against_simulation.diagnose_simulation(rec, sim, simulated_inputs=["ambient", "coolant_inlet"], registry=reg,
                                               only=["fan_heat", "bearing_heat_law", "radiation"])
    assert [f["mechanism"] for f in d.findings] == ["fan_heat"]
    listed = {m["mechanism"]: m for m in d.adequacy["mechanisms"]}
    assert listed["fan_heat"]["status"] == "tested" and listed["fan_heat"]["passed"]
    assert "declares no form" in listed["radiation"]["reason"]


def test_a_bending_the_simulation_lacks_is_named_on_the_drift_it_does_not_heat():
    """The tilt's drift follows the spindle's heat on an X channel the simulation does not move with that heat:
    the heat rule keeps speed heat out of that channel's null, so the bending form is testable there (and the
    heat-path mechanisms, which only rescale what the simulation heats, do not reach it)."""
    import tempfile

    gen, sim = make_sim_case(21, "thermal_tilt", "lumped", 0.2, False)
    with tempfile.TemporaryDirectory() as tmp:
        rec = load_recording(*gen.write(Path(tmp)))
    d = against_simulation.diagnose_simulation(rec, sim, simulated_inputs=gen.info["simulated_inputs"],
                                               only=["thermal_tilt", "bearing_heat_law", "slow_structural_mode"])
    assert [f["mechanism"] for f in d.findings] == ["thermal_tilt"]
    p = against_simulation.prepare(rec, sim, gen.info["simulated_inputs"])
    x = p.channels.index("disp_x_um")
    assert not p.heated[x] and p.heated[p.channels.index("disp_z_um")]
    assert x not in against_simulation._reached(p, {"driver": "speed_power", "reaches": ("displacement",)})


def test_simulate_drive_writes_a_table_diagnose_reads(tmp_path):
    from thermodrift.core.physics.diagnose.concealed import concealed_case

    case = concealed_case(load_network("demo_spindle"), None, 3, dt_s=300.0, hours=8.0)
    table, manifest = tmp_path / "rec.csv", tmp_path / "rec.yaml"
    case.recording.write(table, manifest)
    net = tmp_path / "net.yaml"
    import yaml

    from thermodrift.core import physics
    net.write_text(yaml.safe_dump(physics.network_to_dict(case.baseline)), encoding="utf-8")
    sim = tmp_path / "sim.parquet"
    assert cli.main(["simulate", "--network", str(net), "--drive", str(table), "--manifest", str(manifest),
                     "--out", str(sim)]) == 0
    rec = load_recording(table, manifest)
    frame = simulation_table.read_simulation(sim, rec, manifest)
    assert set(frame.columns) == set(simulation_table.simulated_channels(rec))
    disp = rec.columns("displacement")[0]
    # the network that made the recording, driven by its inputs, reads what it read up to noise and offsets
    r = rec.data[disp].to_numpy() - frame[disp].to_numpy()
    assert np.std(r) < 0.1 * np.std(rec.data[disp].to_numpy())
    assert cli.main(["simulate", "--network", str(net), "--drive", str(table), "--out", str(sim)]) == 2


def test_the_auto_report_gives_every_mechanism_a_standing():
    from types import SimpleNamespace

    from thermodrift.core.physics.diagnose import status

    d = SimpleNamespace(findings=[{"mechanism": "cutting_heat"}], rejected=[
        {"mechanism": "ambient_coupling", "reason": "nested in the baseline: every conductance it adds runs parallel"},
        {"mechanism": "thermal_tilt", "reason": "skipped: no structure or table node"},
        {"mechanism": "sensor_lag", "reason": "screened: its response explains less of the residual"}])
    got = {m["mechanism"]: m["status"] for m in status.listing(
        d, ["ambient_coupling", "cutting_heat", "sensor_lag", "thermal_tilt"])}
    assert got == {"ambient_coupling": "nested", "cutting_heat": "tested", "sensor_lag": "tested",
                   "thermal_tilt": "untestable"}


def _tested(shares, null=10.0):
    folds = np.asarray(shares, float)
    return against_simulation.Tested("m", {"driver": "cutting_power"}, [0], folds * null, 0.0, 10.0, 0.0, 0.0,
                                     np.zeros((2, 1)), np.zeros((2, 1)), fold_null=np.full(len(folds), null))


def test_the_decision_is_the_median_fold_gain_robust_to_one_fold_and_the_final_block_must_improve():
    n = against_simulation.FOLDS + 1
    # one fold far worse (conditions the others lack) does not sink a mechanism explaining the rest
    assert _tested([0.8] * (n - 2) + [-3.0, 0.7]).consistent
    # ... but the final block (the last fold) must be better
    assert not _tested([0.8] * (n - 1) + [-0.1]).consistent
    # a median of 50 % passes only when every fold is better
    assert _tested([0.55] * n).consistent
    assert not _tested([0.55] * (n - 2) + [-0.1, 0.55]).consistent
    # too few folds better
    k = against_simulation.IMPROVED - 1
    assert not _tested([0.9] * (k - 1) + [-0.1] * (n - k) + [0.9]).consistent


def test_a_small_gain_on_every_fold_counts_on_the_drift_only():
    n = against_simulation.FOLDS + 1
    small = _tested([0.2] * n)
    assert not small.consistent and small.steady
    assert small.passes(on_drift=True) and not small.passes(on_drift=False)
    # one fold below the steady share, or a correction below the size bar, and it does not pass
    assert not _tested([0.2] * (n - 1) + [0.02]).passes(on_drift=True)
    low = _tested([0.2] * n)
    low.size = against_simulation.SIZE_MIN / 2
    assert not low.passes(on_drift=True)


def test_a_spindle_side_heat_term_keeps_its_physical_sign_on_the_drift():
    """The drift's simulated sense for the spindle's heat is read from the simulation (a z that falls as the
    spindle warms has sense −1), and the spindle-side forms declare that their sign holds on the drift."""
    from thermodrift.core.physics.diagnose import sim_forms

    t = np.linspace(0.0, 1.0, 50)
    excess = np.column_stack([2.0 * t, 0.5 * t, -3.0 * t])  # hot spindle, column, a z drift that falls
    kinds = ["temperature", "temperature", "displacement"]
    assert sim_forms.hottest(excess, kinds) == 0
    assert sim_forms.sense(excess, kinds, 2) == -1
    assert sim_forms.sense(np.column_stack([excess[:, :2], 3.0 * t]), kinds, 2) == 1
    inputs = sim_forms.Inputs(t, np.ones_like(t), {"ambient": 0.1 * t})
    drift = sim_forms.surfaces(inputs, excess, kinds, 2, excess[:, :2].mean(axis=1) - 0.1 * t)
    assert len(drift) == 2 and np.allclose(drift[0], 1.9 * t)  # the spindle's excess over the air, and the mean
    assert np.allclose(sim_forms.surfaces(inputs, excess, kinds, 1, drift[1])[0], 0.4 * t)
    for mid in ("speed_dependent_convection", "preload_feedback"):
        assert sim_forms.form_of(registry.default().get("mechanism", mid).factory)["drift_sense"] is True


def test_the_semi_synthetic_regression_simulation_reproduces_a_drift_its_temperatures_explain():
    from support import load_file
    from thermodrift.testing.data import tiny_recording

    bench = load_file(ROOT / "benchmarks" / "bench_diagnose_simulation.py")
    rec = tiny_recording()
    temps = [c for c in rec.channels if rec.channels[c].role == "temperature"]
    drift = [c for c in rec.channels if rec.channels[c].role == "displacement"]
    rec.data[drift[0]] = 3.0 * rec.data[temps[0]] - 2.0 * rec.data[temps[-1]] + 1.5
    sim = bench.regression_simulation(rec)
    assert list(sim.columns) == drift and np.allclose(sim.index, rec.time_s)
    assert np.abs(sim[drift[0]].to_numpy() - rec.data[drift[0]].to_numpy()).max() < 0.05
    # a drift the temperatures do not explain (noise) is not reproduced
    rec.data[drift[1]] = np.random.default_rng(0).normal(0.0, 1.0, len(rec.time_s))
    residual = bench.regression_simulation(rec)[drift[1]].to_numpy() - rec.data[drift[1]].to_numpy()
    assert residual.std() > 0.5


def test_a_small_response_to_the_hall_air_is_read_from_the_traces_and_cutting_that_follows_the_speed_is_not():
    from thermodrift.core.physics.diagnose import sim_forms

    t = np.arange(0.0, 30 * 3600.0, 120.0)
    rng = np.random.default_rng(0)
    r = np.repeat(rng.choice([0.0, 0.4, 0.7, 1.0], len(t) // 90 + 1), 90)[:len(t)]
    hvac = np.zeros(len(t))  # the hall's thermostat and doors: an Ornstein-Uhlenbeck wander of about 0.4 K
    for i in range(1, len(t)):
        hvac[i] = hvac[i - 1] * np.exp(-120.0 / 3600.0) + rng.normal(0.0, 0.1)
    air = 1.5 * np.sin(2 * np.pi * t / 86400.0) + hvac
    cutting = 3.0 * r + 0.2 * (r > 0)  # kW while running: it follows the programme
    inputs = sim_forms.Inputs(t, r, {"ambient": air - air[0], "cutting_power": cutting - cutting[0]})
    heat = inputs.lag(r ** sim_forms.HEAT_EXPONENT, 3600.0)
    sigma = np.array([0.05])
    # the simulation moves the drift with the spindle's heat (100 µm) and a little with the hall air (0.65 µm peak
    # to peak: under 1 % of the range, 13 times the noise); it has no cutting heat
    excess = (100.0 * heat + 0.2 * inputs.lag(air, 1800.0))[:, None]
    found = sim_forms.responses(inputs, excess, sigma)
    assert found["speed"][0] and sim_forms.detect_inputs(found) == ["ambient"]
    # without the air path the hall air is not read as driving the simulation
    assert sim_forms.detect_inputs(sim_forms.responses(inputs, (100.0 * heat)[:, None], sigma)) == []
