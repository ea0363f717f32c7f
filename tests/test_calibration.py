"""Calibration: known parameters inside their intervals, unidentifiable ones named, the auto baseline, the CLI."""

import json
from pathlib import Path

import numpy as np
import pytest

from thermodrift.core import physics
from thermodrift.core.errors import InputError
from thermodrift.core.physics import calibration as cal
from thermodrift.core.physics import scenarios, synthetic
from thermodrift.core.physics.scenarios import Block
from thermodrift.core.physics.synthetic import speed_only, synthesize

TWO_NODE = Path(__file__).parent / "data" / "two_node_network.yaml"  # two measured nodes, one displacement
# The sensor node ``a`` reaches ambient only through ``m``, a massless joint without a sensor: only the series
# conductance G1·G2/(G1 + G2) shows in the data.
SERIES = {
    "name": "series", "reference_speed_rpm": 6000,
    "nodes": {"a": {"capacity_J_K": 5000, "group": "bearing"}, "m": {"capacity_J_K": 1.0, "group": "housing"}},
    "edges": [{"a": "a", "b": "m", "G_W_K": 3.0}, {"a": "m", "b": "ambient", "G_W_K": 2.0, "kind": "convection"}],
    "sources": {"heat": {"type": "bearing", "node": "a", "viscous_W": 60.0}},
    "sensors": {"T_a": {"node": "a", "noise_K": 0.01}},
}
FREE = ["edges.*.G_W_K", "sources.heat.viscous_W"]


def _scenario(dt_s=60.0):
    return scenarios.blocks([Block(0.25), Block(2, 3000), Block(1.5), Block(2, 6000), Block(1.5)], dt_s)


def test_known_parameters_fall_inside_their_intervals_over_seeds():
    truth = physics.load_network(TWO_NODE)
    values = truth.parameters()
    start = truth.with_values({"edges.a-b.G_W_K": 4.5, "edges.a-ambient.G_W_K": 0.6, "edges.b-ambient.G_W_K": 6.0,
                               "sources.heat.viscous_W": 40.0})
    for seed in range(3):
        # Pt100 offsets are drawn per seed: the projected sensor offsets must absorb them.
        rec = synthesize(truth, _scenario(), seed).recording
        result = cal.calibrate(rec, start, free=FREE, level=0.99)
        assert {e.name for e in result.estimates} == {"edges.a-b.G_W_K", "edges.a-ambient.G_W_K",
                                                      "edges.b-ambient.G_W_K", "sources.heat.viscous_W"}
        for e in result.estimates:
            assert e.low <= values[e.name] <= e.high, (seed, e)
            assert e.ratio < 1.1, f"interval of {e.name} is uninformative: {e}"  # the test must be able to fail
        assert not result.unidentifiable
        # noise σ from the high-frequency residual matches the simulated sensor noise
        assert result.sigma["T_a"] == pytest.approx(0.01, rel=0.3)
        assert result.sigma["disp_z"] == pytest.approx(0.05, rel=0.3)
        # sensitivities are solved linearly inside each step
        assert result.linear["disp_z"]["a"] == pytest.approx(2.0, rel=0.02)
        assert result.linear["disp_z"]["b"] == pytest.approx(3.0, rel=0.02)
        assert result.rmse["disp_z"] < 0.07 and result.rmse["disp_z"] < result.rmse_initial["disp_z"]


def test_series_conductances_without_a_sensor_between_are_reported_unidentifiable():
    truth = physics.network_from_dict(SERIES)
    rec = synthesize(truth, _scenario(), 0).recording
    start = truth.with_values({"edges.a-m.G_W_K": 1.5, "edges.m-ambient.G_W_K": 5.0})
    result = cal.calibrate(rec, start, free=FREE)
    flagged = {u["parameter"] for u in result.unidentifiable}
    assert flagged == {"edges.a-m.G_W_K", "edges.m-ambient.G_W_K"}
    (direction,) = result.null_directions
    assert set(direction["log_combination"]) == {"edges.a-m.G_W_K", "edges.m-ambient.G_W_K"}
    # the identifiable combination is recovered: series conductance 1.2 W/K, heat 60 W
    g1, g2 = result.estimate("edges.a-m.G_W_K").value, result.estimate("edges.m-ambient.G_W_K").value
    assert g1 * g2 / (g1 + g2) == pytest.approx(1.2, rel=0.01)
    heat = result.estimate("sources.heat.viscous_W")
    assert heat.low <= 60.0 <= heat.high and heat.ratio < 1.05


def _auto_truth_recording(seed=0):
    """Three sensor nodes heated from the speed, one slow hidden node in the displacement (an auto-like truth)."""
    spec = {
        "name": "auto_like", "reference_speed_rpm": 6000,
        "nodes": {"s1": {"capacity_J_K": 1e4, "group": "bearing"}, "s2": {"capacity_J_K": 1e4, "group": "housing"},
                  "s3": {"capacity_J_K": 1e4}, "h": {"capacity_J_K": 1e4, "group": "shaft"}},
        "edges": [{"a": n, "b": "ambient", "G_W_K": g, "kind": "convection"}
                  for n, g in (("s1", 5.0), ("s2", 2.0), ("s3", 8.0), ("h", 1.0))],
        "sources": {f"q_{n}": {"type": "bearing", "node": n, "viscous_W": q, "viscous_exponent": 1.2}
                    for n, q in (("s1", 60.0), ("s2", 10.0), ("s3", 5.0), ("h", 4.0))},
        "outputs": {"z": {"axis": "z", "sensitivity_um_K": {"s1": 1.5, "h": -4.0}}},
        "sensors": {"T1": {"node": "s1", "noise_K": 0.01}, "T2": {"node": "s2", "noise_K": 0.01},
                    "T3": {"node": "s3", "noise_K": 0.01}, "dz": {"output": "z", "noise_um": 0.05}},
    }
    net = physics.network_from_dict(spec)
    scen = scenarios.blocks([Block(0.2), Block(3, 2000), Block(2), Block(3, 6000), Block(2), Block(2, 4000)], 60.0)
    return net, synthesize(net, scen, seed).recording


def test_auto_baseline_states_its_assumptions_and_fits_an_auto_like_truth():
    _, rec = _auto_truth_recording()
    auto = cal.auto_network(rec, hidden_nodes=1)
    assert auto.channel_nodes == {"T1": "T1", "T2": "T2", "T3": "T3"}
    # steady rises 12, 5 and 0.6 K: ≥ 50 % of the largest is bearing, ≥ 10 % housing, else structure
    assert [n.group for n in auto.network.nodes] == ["bearing", "housing", "structure", "shaft"]
    assert not any(e.b != "ambient" for e in auto.network.edges), "the baseline has no conduction between nodes"
    result = cal.calibrate(rec, hidden_nodes=1)
    doc = result.to_dict()
    assert doc["assumptions"] == list(cal.AUTO_ASSUMPTIONS)
    assert json.loads(json.dumps(doc)) == doc
    # the truth is inside the auto family: the fit reaches the noise and recovers the heat exponent
    assert result.rmse["T1"] < 0.02 and result.rmse["dz"] < 0.08
    p = result.estimate("heat_exponent")
    assert p.low <= 1.2 <= p.high
    # capacity 1e4 J/K as in the truth, so conductances come out in W/K
    g1 = result.estimate("G[T1]")
    assert g1.low <= 5.0 <= g1.high


def test_auto_needs_a_running_speed_channel():
    _, rec = _auto_truth_recording()
    stopped = rec.select(np.flatnonzero(rec.speed.to_numpy() == 0)[:10])
    with pytest.raises(InputError, match="speed"):
        cal.auto_network(stopped)


def test_bad_free_pattern_and_targets_are_input_errors():
    truth = physics.load_network(TWO_NODE)
    rec = synthesize(truth, _scenario(), 0).recording
    with pytest.raises(InputError, match="match nothing"):
        cal.calibrate(rec, truth, free=["edges.*.nonsense"])
    with pytest.raises(InputError, match="not displacement channels"):
        cal.calibrate(rec, truth, free=FREE, targets=["T_a"])


def test_fit_is_deterministic_on_a_slowed_clock(monkeypatch):
    """No wall-clock stop: a clock that jumps an hour per reading changes nothing but the reported seconds."""
    import time as time_module

    truth = physics.load_network(TWO_NODE)
    rec = synthesize(truth, _scenario(), 0).recording
    start = truth.with_values({"edges.a-b.G_W_K": 9.0})
    first = cal.calibrate(rec, start, free=FREE, starts=2, seed=3)
    ticks = iter(range(0, 10**9, 3600))
    monkeypatch.setattr(time_module, "perf_counter", lambda: float(next(ticks)))
    monkeypatch.setattr(time_module, "time", lambda: float(next(ticks)))
    second = cal.calibrate(rec, start, free=FREE, starts=2, seed=3)
    assert first.stop == second.stop == "tolerance"
    assert first.evaluations == second.evaluations
    assert [e.value for e in first.estimates] == [e.value for e in second.estimates]
    assert first.rmse == second.rmse and first.cost <= first.cost_initial


def test_evaluation_cap_is_reported_and_keeps_the_best_point():
    truth = physics.load_network(TWO_NODE)
    rec = synthesize(truth, _scenario(), 0).recording
    start = truth.with_values({"edges.a-b.G_W_K": 9.0})
    result = cal.calibrate(rec, start, free=FREE, max_evaluations=2)
    assert result.stop == "evaluation_cap"
    assert result.cost <= result.cost_initial
    assert all(result.rmse[c] <= result.rmse_initial[c] for c in result.rmse if result.channel_kind[c] == "displacement")


def test_auto_network_reaches_the_noise_floor_when_nothing_is_missing():
    """The null case: speed-driven heat only; every channel ends within 1.5 × its noise σ, none gets worse."""
    rec = speed_only(0).recording
    result = cal.calibrate(rec, hidden_nodes=1, starts=2)
    noise = {"T_front": 0.02, "T_rear": 0.02, "T_housing": 0.02, "dz": 0.1}
    for c, sigma in noise.items():
        assert result.rmse[c] <= 1.5 * sigma, (c, result.rmse[c], result.rmse_initial[c])
    assert result.rmse["dz"] <= result.rmse_initial["dz"]
    assert result.stop == "tolerance"
    assert result.to_dict()["rmse"] == result.rmse and "rmse_initial" in result.to_dict()
    for name, (lo, hi) in result.linear_ci["dz"].items():  # every sensitivity has a finite interval
        assert lo is not None and hi is not None and lo <= result.linear["dz"][name] <= hi


def test_calibrate_cli_auto_writes_every_output(tmp_path, cli):
    _, rec = _auto_truth_recording()
    table, manifest = tmp_path / "rec.csv", tmp_path / "rec.manifest.yaml"
    rec.write(table, manifest)
    out = tmp_path / "cal"
    proc = cli(tmp_path, "calibrate", str(table), "--manifest", str(manifest), "--network", "auto", "--hidden-nodes",
               "1", "--out", str(out), "--starts", "2", "--no-progress", timeout=300)
    assert proc.returncode == 0, proc.stderr
    for name in ("calibration.json", "calibrated_network.yaml", "mismatch.json", "mismatch_heatmap.png",
                 "before_after.png"):
        assert (out / name).stat().st_size > 0, name
    doc = json.loads((out / "calibration.json").read_text(encoding="utf-8"))
    assert doc["assumptions"] and "heat_exponent" in doc["estimates"]
    assert doc["rmse"]["dz"] < doc["rmse_initial"]["dz"]
    assert doc["objective"]["stop"] in ("tolerance", "evaluation_cap") and len(doc["starts"]) == 2
    assert json.loads((out / "mismatch.json").read_text(encoding="utf-8"))["ranked_windows"]
    assert "top mismatch windows" in proc.stdout
    calibrated = physics.load_network(str(out / "calibrated_network.yaml"))
    assert calibrated.output("dz").sensitivity_um_K  # the estimated map is written into the spec
    bad = cli(tmp_path, "calibrate", str(table), "--manifest", str(manifest), "--targets", "T1", "--out", str(out),
              timeout=120)
    assert bad.returncode == 2 and "not displacement channels" in bad.stderr


def test_fit_grid_follows_the_recordings_time_scales_not_its_sampling():
    """The same programme at 15 s and at 1 s is fitted on the same grid: every speed change on it."""
    grids = []
    for dt in (15.0, 1.0):
        scen = scenarios.blocks([Block(0.5)] + [b for n in (1250, 5000) for b in (Block(3.0, n), Block(2.0))], dt)
        t, speed = scen.time_s, scen.frame["speed_rpm"].to_numpy()
        rows, step = cal.fit_rows(t, speed, time_constants_s=[1800.0])
        changes = np.flatnonzero(np.diff(speed)) + 1
        assert set(changes) <= set(rows)
        grids.append((step, len(rows)))
    assert grids[0] == grids[1]  # shortest block 0.5 h / 8 = 225 s, however finely sampled
    assert grids[0][0] == 225.0 and grids[0][1] < 200


def test_grouped_conductances_share_one_factor_per_node_group_and_jitter_moves_only_the_start():
    _, rec = _auto_truth_recording()
    plain = cal.auto_network(rec, hidden_nodes=1)
    grouped = cal.auto_network(rec, hidden_nodes=1, grouped=True)
    names = [p.name for p in grouped.free if p.projected_by is None]
    # three temperature nodes in three groups, one hidden node with its own conductance, the shared exponent
    assert sorted(names) == sorted(["G[bearing]×", "G[housing]×", "G[structure]×", "G[hidden_1]", "heat_exponent"])
    factor = next(p for p in grouped.free if p.name == "G[bearing]×")
    g_start = {p.paths[0]: p.value for p in plain.free if p.name.startswith("G[")}
    assert factor.path_values(2.0) == {path: 2.0 * g_start[path] for path in factor.paths}
    result = cal.calibrate(rec, hidden_nodes=1, grouped=True, intervals=False)
    assert result.stop == "tolerance" and result.rmse["dz"] <= result.rmse_initial["dz"]
    # a jittered start searches from elsewhere but the never-worse guard still compares with the plain start
    plain_fit = cal.calibrate(rec, hidden_nodes=1, intervals=False)
    jittered = cal.calibrate(rec, hidden_nodes=1, intervals=False, jitter_seed=1)
    assert jittered.rmse_initial == plain_fit.rmse_initial
    assert jittered.starts[0]["values"] != plain_fit.starts[0]["values"]


def test_auto_prior_strength_is_chosen_on_a_later_block_and_pins_a_flat_direction():
    """The auto network gets a prior centred on its unjittered start, its strength chosen by fitting before a
    held-out later block and predicting it. At one running speed the heat exponent p is flat ((n/n_ref)^p = 1):
    without the prior jittered starts end at different p, with it at the same fit. A spec network gets none."""
    rec = speed_only(0).recording
    plain = cal.calibrate(rec, hidden_nodes=1, intervals=False)
    prior = plain.to_dict()["prior"]
    assert plain.prior.strength in cal.STRENGTH_GRID and prior["strength_per_row"] == plain.prior.strength
    fit_s, held_s = prior["validation"]["fit_s"], prior["validation"]["held_out_s"]
    assert fit_s[1] < held_s[0] and held_s[1] == rec.time_s[-1]
    assert set(prior["validation"]["loss_per_row"]) == {str(s) for s in cal.STRENGTH_GRID}
    start = {p.name: p.value for p in cal.auto_network(rec, hidden_nodes=1).free if p.projected_by is None}
    assert prior["centre"] == pytest.approx({k: np.log(v) for k, v in start.items()})

    one_speed = [Block(0.5)] + [Block(3.0, 3000), Block(2.0)] * 3
    flat = synthesize(physics.network_from_dict(synthetic.SPEED_ONLY), scenarios.blocks(one_speed, 60.0), 0).recording
    exponents = {}
    for strength in (0.0, None):
        fits = [cal.calibrate(flat, hidden_nodes=1, intervals=False, jitter_seed=seed, prior_strength=strength)
                for seed in (1, 2, 3)]
        exponents[strength] = [f.estimate("heat_exponent").value for f in fits]
    assert max(exponents[0.0]) / min(exponents[0.0]) > 1.25, exponents  # flat: the end point is the start
    assert max(exponents[None]) / min(exponents[None]) < 1.01, exponents
    truth = physics.load_network(TWO_NODE)
    assert cal.calibrate(synthesize(truth, _scenario(), 0).recording, truth, free=FREE).prior is None
