"""A mechanism that only adds conductances parallel to ones the baseline already fits, or a tilt between two nodes
a displacement channel already reads, is a refit of the baseline, not missing physics: screening reports it as
nested and does not test it; against a network whose conductances are fixed, or whose expansion map leaves a node
out, it is tested as before."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from thermodrift.core import physics
from thermodrift.core import registry as registry_module
from thermodrift.core.physics.calibration import auto_network
from thermodrift.core.physics.diagnose import screening
from thermodrift.core.physics.diagnose.concealed import concealed_case
from thermodrift.core.physics.network import TemperatureSensor
from thermodrift.core.physics.scenarios import Scenario


@pytest.fixture(scope="module")
def auto_case():
    case = concealed_case(physics.load_network("demo_spindle"), None, 4, hours=14.0, dt_s=120.0)
    auto = auto_network(case.recording)
    free = frozenset(p for fp in auto.free for p in fp.paths)
    return case.recording, auto.network, free


def _screen(rec, net, free):
    channels = [s.name for s in net.sensors]
    sigma = np.array([s.noise_K if isinstance(s, TemperatureSensor) else s.noise_um for s in net.sensors])
    sigma = np.maximum(sigma, 0.01)
    scenario = Scenario.from_recording(rec)
    measured = rec.data[channels].to_numpy(dtype=float)
    base = screening.baseline_of(net, scenario, channels, measured, np.arange(len(rec)), sigma)
    return screening.candidates(registry_module.default(), base, scenario, channels, rec, None, free)


def test_parallel_conductances_to_the_ambient_are_nested_in_the_auto_baseline(auto_case):
    rec, net, free = auto_case
    for mid in ("ambient_coupling", "radiation"):
        mech = registry_module.default().get("mechanism", mid).factory()
        augmented, _ = mech.declare(net)
        twins = screening.nested(net, augmented, free)
        assert twins and all(f"edges.{t}.G_W_K" in free for t in twins)
        assert screening.nested(net, augmented, frozenset()) == []  # fixed conductances: a real change
    coolant = registry_module.default().get("mechanism", "coolant_coupling").factory()
    assert screening.nested(net, coolant.declare(net)[0], free) == []  # a new node and boundary: not nested


def test_screening_reports_nested_mechanisms_and_tests_them_when_conductances_are_fixed(auto_case):
    rec, net, free = auto_case
    cands, rejected = _screen(rec, net, free)
    reasons = {r["mechanism"]: r["reason"] for r in rejected}
    assert not any(c.mechanism in ("ambient_coupling", "radiation") for c in cands)
    assert reasons["ambient_coupling"].startswith("nested in the baseline") and "--network" in reasons["ambient_coupling"]
    assert cands  # the others are still screened
    fixed, rejected_fixed = _screen(rec, net, frozenset())
    assert {"ambient_coupling", "radiation"} <= {c.mechanism for c in fixed}
    # a tilt between nodes the expansion map reads stays nested: the linear refit solves those sensitivities
    assert [r["mechanism"] for r in rejected_fixed if r["reason"].startswith("nested")] == ["thermal_tilt"]


def test_a_tilt_between_nodes_the_expansion_map_reads_is_reported_nested_and_tested_once_a_node_is_left_out(
        auto_case):
    rec, net, free = auto_case
    tilt = registry_module.default().get("mechanism", "thermal_tilt").factory
    assert tilt.places(net) == [] and tilt.unplaced(net)  # the auto map reads every node: no new pair
    reasons = {r["mechanism"]: r["reason"] for r in _screen(rec, net, free)[1]}
    assert reasons["thermal_tilt"].startswith("nested in the baseline") and "sensitivities" in reasons["thermal_tilt"]
    out = net.outputs[0]
    cold = next(n for n in out.sensitivity_um_K if net.node(n).group in ("structure", "table"))
    partial = net.replace(dataclasses.replace(out, sensitivity_um_K={n: k for n, k in out.sensitivity_um_K.items()
                                                                     if n != cold}))
    assert tilt.places(partial) and tilt.unplaced(partial) is None
    cands, rejected = _screen(rec, partial, free)
    assert any(c.mechanism == "thermal_tilt" and c.options["cold"] == cold for c in cands)
    assert "thermal_tilt" not in {r["mechanism"] for r in rejected}


def test_a_tilt_without_a_cold_node_is_skipped_with_the_sensor_it_needs():
    tilt = registry_module.default().get("mechanism", "thermal_tilt").factory
    net = physics.load_network("demo_spindle")
    cold = [n.name for n in net.nodes if n.group in ("structure", "table")]
    assert tilt.places(net) and tilt.unplaced(net) is None
    hot_only = net.replace(*[dataclasses.replace(n, group="housing") for n in net.nodes if n.name in cold])
    assert tilt.places(hot_only) == []
    assert tilt.unplaced(hot_only).startswith("skipped: the network has no structure or table node")
