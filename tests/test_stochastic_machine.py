"""The stochastic engine on machine networks: the network as an SDE over its speed levels, and ``diagnose
--stochastic`` naming a planted mechanism by likelihood ratio."""

import json

import numpy as np
import pytest

from thermodrift.core import physics
from thermodrift.core.physics import scenarios
from thermodrift.core.physics.scenarios import Block
from thermodrift.core.physics.stochastic import machine
from thermodrift.core.physics.stochastic.fit import fit, loglik
from thermodrift.core.physics.synthetic import synthesize

SPEC = {
    "name": "two", "reference_speed_rpm": 6000,
    "nodes": {"a": {"capacity_J_K": 5000, "group": "bearing"}, "b": {"capacity_J_K": 20000, "group": "housing"}},
    "edges": [{"a": "a", "b": "b", "G_W_K": 3.0}, {"a": "b", "b": "ambient", "G_W_K": 6.0, "kind": "convection"},
              {"a": "a", "b": "ambient", "G_W_K": 0.5, "kind": "convection"}],
    "sources": {"heat": {"type": "bearing", "node": "a", "viscous_W": 60.0}},
    "sensors": {"T_a": {"node": "a", "noise_K": 0.02}, "T_b": {"node": "b", "noise_K": 0.02}},
}


def _recording(seed=0, net=None):
    net = net or physics.network_from_dict(SPEC)
    scen = scenarios.blocks([Block(0.5), Block(2, 3000), Block(1.5), Block(2, 6000), Block(2)], 120.0)
    return net, synthesize(net, scen, seed).recording


def test_the_network_sde_prefers_the_true_conductance_and_estimates_its_noise():
    net, rec = _recording()
    model = machine.NetworkModel(net, rec, factors={"G_ab": ("edges.a-b.G_W_K",)})
    assert len(model.levels) == 3 and model.channels == ["T_a", "T_b"]
    start = {p.name: p.value for p in model.parameters}
    ll = loglik(model, model.data, start)
    assert ll > loglik(model, model.data, {**start, "k.G_ab": 2.0}) + 50
    est = fit(machine.Frozen(model, {"k.G_ab": 1.0}), model.data, seed=0, starts=1)
    assert est.loglik >= ll
    for c in ("T_a", "T_b"):  # the recording's sensor noise is 0.02 K (plus Pt100 offsets the model does not know)
        lo, hi = est.intervals[f"r.{c}"]
        assert 0.01 < lo < est.values[f"r.{c}"] < hi < 0.04


def test_diagnose_stochastic_writes_its_selection_report(tmp_path, cli):
    """The door on a machine recording: the auto baseline refined as a stochastic model, then each mechanism by
    likelihood ratio; the report states the path, the findings and why every other mechanism was left out."""
    spec = {**SPEC, "sources": {**SPEC["sources"], "cut": {"type": "cutting", "split": {"a": 1.0}, "fraction": 0.1}}}
    scen = scenarios.blocks([Block(0.5), Block(2, 3000, cutting_power_W=800), Block(1), Block(2, 3000),
                             Block(1.5, 0, cutting_power_W=800), Block(2)], 120.0)
    rec = synthesize(physics.network_from_dict(spec), scen, 1).recording
    table, manifest = tmp_path / "r.csv", tmp_path / "r.yaml"
    rec.write(table, manifest)
    out = tmp_path / "dx"
    proc = cli(tmp_path, "diagnose", str(table), "--manifest", str(manifest), "--stochastic", "--mechanisms",
               "cutting_heat", "axis_drive_heat", "--max-rounds", "1", "--out", str(out), timeout=300)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert doc["kind"] == "stochastic_mechanisms" and np.isfinite(doc["baseline"]["loglik"])
    step = doc["selection_path"][1]
    assert step["name"] == "cutting_heat" and step["df"] == 1 and step["level"] == pytest.approx(0.01 / 2)
    assert step["accepted"] == bool(doc["findings"]) == (step["p_value"] < step["level"])
    reasons = {r["mechanism"]: r["reason"] for r in doc["rejected"]}
    assert reasons["axis_drive_heat"].startswith("skipped: ")  # no axis velocity channel
    assert doc["verdict"] in proc.stdout


def test_a_mechanism_switched_off_gives_its_parent_back():
    """Where each candidate starts besides its defaults: the parent's own value on a path the parent has (a lag or
    an exponent offset 0; the lag's low bound lowered towards 0), the declared neutral value on a new one."""
    from thermodrift.plugins.mechanisms.ambient_coupling import AmbientCoupling
    from thermodrift.plugins.mechanisms.bearing_heat_law import BearingHeatLaw
    from thermodrift.plugins.mechanisms.sensor_lag import SensorLag

    net = physics.network_from_dict(SPEC)
    _, new = SensorLag(sensors=["T_a"]).declare(net)
    assert new[0].low == 1.0 and machine.reaching_off(SensorLag, new)[0].low == pytest.approx(1e-3)
    assert machine.nested_start(SensorLag, net, machine.reaching_off(SensorLag, new)) == {"lag_s": pytest.approx(1e-3)}
    _, rec = _recording(net=net)  # the lag is a state: switched off, the sensor reads its node
    lagged = machine.NetworkModel(SensorLag(sensors=["T_a"]).apply(net), rec, free=new)
    plain = machine.NetworkModel(net, rec)
    values = {p.name: p.value for p in plain.parameters}
    assert lagged.channels == plain.channels == ["T_a", "T_b"]
    assert loglik(lagged, lagged.data, {**values, "lag_s": 1e-3}) == pytest.approx(
        loglik(plain, plain.data, values), abs=0.01)
    assert loglik(lagged, lagged.data, {**values, "lag_s": 600.0}) < loglik(plain, plain.data, values) - 10
    _, new = BearingHeatLaw().declare(net)
    off = machine.nested_start(BearingHeatLaw, net, machine.reaching_off(BearingHeatLaw, new))
    assert off["exponent_shift"] == 0.0 and off["viscosity_coeff_per_K"] < 1e-6
    _, new = AmbientCoupling().declare(net)
    assert machine.nested_start(AmbientCoupling, net, new)["G_W_K"] == new[0].low < 0.01


def test_a_candidate_fit_never_ends_below_the_model_it_extends():
    """Each candidate also starts where it is switched off, so its fit ends at or above its parent's likelihood
    (it once ended far below, from its defaults, and max(LR, 0) hid it); one that gains nothing is nested."""
    _, rec = _recording()
    doc = machine.select_mechanisms(rec, only=["bearing_heat_law", "speed_dependent_convection"], max_rounds=1)
    base = doc["baseline"]["loglik"]
    cands = doc["selection_path"][1]["candidates"]
    assert doc["selection_path"][1]["parent_loglik"] == base
    assert {c["mechanism"] for c in cands} == {"bearing_heat_law", "speed_dependent_convection"}
    for c in cands:
        assert c["off_loglik"] == pytest.approx(base, abs=0.05), c
        assert c["loglik"] >= base - 0.05, c
    reasons = {r["mechanism"]: r["reason"] for r in doc["rejected"]}
    assert reasons["speed_dependent_convection"].startswith("nested")


def test_a_growth_at_once_is_not_tested_where_samples_are_slower_than_the_spindles_heating():
    """Samples 120 s apart: a step within one of them cannot be told from the nose's fast heating, so the
    centrifugal growth is skipped with the reason, not fitted."""
    _, rec = _recording()
    doc = machine.select_mechanisms(rec, only=["centrifugal_growth"], max_rounds=1)
    reasons = {r["mechanism"]: r["reason"] for r in doc["rejected"]}
    assert reasons["centrifugal_growth"].startswith("skipped: samples 120 s apart")
    assert len(doc["selection_path"]) == 1 and not doc["findings"]


def test_a_candidate_its_parameters_cannot_switch_off_is_not_tested_by_likelihood_ratio():
    """The slow structural mode's conductance into its new node is fixed: switched off as far as its parameters
    allow, it still loads the network, so it is not nested in its parent and the χ² law of the likelihood ratio
    does not hold; it is named so and never accepted."""
    _, rec = _recording()
    doc = machine.select_mechanisms(rec, only=["slow_structural_mode"], max_rounds=1)
    reasons = {r["mechanism"]: r["reason"] for r in doc["rejected"]}
    assert "not nested, so no likelihood-ratio test" in reasons["slow_structural_mode"]
    assert len(doc["selection_path"]) == 1 and not doc["findings"]
