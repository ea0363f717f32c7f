"""The thermal network engine against analytic solutions, and its spec validation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
import yaml

from thermodrift.core import physics
from thermodrift.core.errors import InputError
from thermodrift.core.physics import scenarios
from thermodrift.core.physics.network import BearingSource, Edge, Network, Node, Output

N_REF = 5000.0


def two_node(q_W=50.0, c_a=2000.0, c_b=20000.0, g_ab=4.0, g_b=10.0) -> Network:
    """A heated node A joined to B, which alone exchanges heat with ambient."""
    return Network(
        "two_node", (Node("a", c_a, "bearing"), Node("b", c_b, "housing")),
        edges=(Edge("a-b", "a", "b", g_ab), Edge("b-amb", "b", "ambient", g_b, kind="convection")),
        sources=(BearingSource("heat", "a", viscous_W=0.0, load_W=q_W),),
        outputs=(Output("z", "z", {"a": 2.0, "b": 1.0}),), reference_speed_rpm=N_REF)


def run_at_speed(net, hours_on, hours_off=0.0, dt_s=30.0, speed=N_REF, ambient=20.0, method="exact"):
    prog = [scenarios.Block(hours_on, speed)] + ([scenarios.Block(hours_off)] if hours_off else [])
    return physics.simulate(net, scenarios.blocks(prog, dt_s, ambient=scenarios.constant(ambient)), method=method)


def test_two_node_steady_state_and_time_constants_match_analytic():
    q, c_a, c_b, g_ab, g_b = 50.0, 2000.0, 20000.0, 4.0, 10.0
    net = two_node(q, c_a, c_b, g_ab, g_b)
    res = run_at_speed(net, hours_on=40.0, dt_s=60.0)
    t_b = 20.0 + q / g_b
    t_a = t_b + q / g_ab
    np.testing.assert_allclose(res.temperatures.iloc[-1], [t_a, t_b], rtol=1e-6)
    np.testing.assert_allclose(res.displacements["z"].iloc[-1], 2.0 * (t_a - 20) + (t_b - 20), rtol=1e-6)
    # Analytic eigenvalues of C⁻¹L for the chain a–b–ambient.
    tr = -(g_ab / c_a) - (g_ab + g_b) / c_b
    det = (g_ab / c_a) * (g_ab + g_b) / c_b - (g_ab / c_a) * (g_ab / c_b)
    lam = np.array([(tr - np.sqrt(tr ** 2 - 4 * det)) / 2, (tr + np.sqrt(tr ** 2 - 4 * det)) / 2])
    taus = physics.CompiledNetwork(net).time_constants_s(N_REF)
    np.testing.assert_allclose(np.sort(taus), np.sort(-1 / lam), rtol=1e-10)
    # The whole trajectory equals the modal solution T(t) = T_ss + V e^{Λt} V⁻¹ (T0 − T_ss).
    A = np.array([[-g_ab / c_a, g_ab / c_a], [g_ab / c_b, -(g_ab + g_b) / c_b]])
    w, V = np.linalg.eig(A)
    t = res.temperatures.index.to_numpy()
    x0 = np.array([20.0 - t_a, 20.0 - t_b])
    modal = np.linalg.solve(V, x0)
    analytic = np.array([t_a, t_b]) + (V @ (modal[:, None] * np.exp(np.outer(w, t)))).T
    np.testing.assert_allclose(res.temperatures.to_numpy(), analytic, atol=1e-9)


def test_steps_six_times_the_fastest_time_constant_stay_stable():
    net = two_node(c_a=300.0, g_ab=20.0)  # fastest τ ≈ 14 s
    tau_min = physics.CompiledNetwork(net).time_constants_s(N_REF).min()
    dt = 90.0  # divides the 3 h blocks, so both grids switch at the same instant
    assert dt >= 6 * tau_min
    fine = run_at_speed(net, 3.0, 3.0, dt_s=dt / 60)
    for method in ("exact", "backward_euler"):
        coarse = run_at_speed(net, 3.0, 3.0, dt_s=dt, method=method)
        T = coarse.temperatures["a"].to_numpy()
        assert np.all(np.isfinite(T))
        rising = T[coarse.scenario.frame["speed_rpm"].to_numpy() > 0]
        assert np.all(np.diff(rising) >= -1e-9), f"{method} oscillates at dt = 6 τ_min"
        ref = fine.temperatures["a"].reindex(coarse.temperatures.index, method="nearest").to_numpy()
        tol = 1e-6 if method == "exact" else 0.05 * (ref.max() - 20)
        assert np.max(np.abs(T - ref)) < tol, method


def test_speed_dependent_convection_makes_warm_up_faster_than_cool_down():
    c, g0, g_rot = 10000.0, 2.0, 6.0
    net = Network("one", (Node("shaft", c, "shaft"),),
                  edges=(Edge("conv", "shaft", "ambient", g0, "convection", G_rot_W_K=g_rot, rot_exponent=0.7),),
                  sources=(BearingSource("heat", "shaft", 0.0, 80.0),), reference_speed_rpm=N_REF)
    res = run_at_speed(net, hours_on=10.0, hours_off=20.0, dt_s=10.0)
    T = res.temperatures["shaft"]
    t = T.index.to_numpy()
    on = t <= 10 * 3600

    def tau(times, values):
        start, end = values[0], values[-1]
        crossed = np.flatnonzero(np.abs(values - start) >= 0.6321 * abs(end - start))[0]
        return times[crossed] - times[0]

    tau_up = tau(t[on], T.to_numpy()[on])
    tau_down = tau(t[~on] - t[~on][0], T.to_numpy()[~on])
    assert tau_up == pytest.approx(c / (g0 + g_rot), rel=0.01)
    assert tau_down == pytest.approx(c / g0, rel=0.01)
    assert tau_up < tau_down / 3


def test_viscosity_law_lowers_heat_as_the_bearing_warms():
    hot = two_node()
    law = physics.BearingSource("heat", "a", viscous_W=50.0, load_W=0.0, viscous_exponent=1.0,
                                viscosity_coeff_per_K=0.02, viscosity_ref_degC=20.0)
    thin = hot.replace(law)
    stiff = hot.replace(dataclasses.replace(law, viscosity_coeff_per_K=0.0))
    end_thin = run_at_speed(thin, 20.0).temperatures["a"].iloc[-1]
    end_stiff = run_at_speed(stiff, 20.0).temperatures["a"].iloc[-1]
    assert end_stiff == pytest.approx(20 + 50 / 10 + 50 / 4, rel=1e-6)
    # Q = 50 (1 − 0.02 ΔT_a) with ΔT_a = Q (1/4 + 1/10): closed form of the linearised law.
    q = 50 / (1 + 50 * 0.02 * (1 / 4 + 1 / 10))
    assert end_thin == pytest.approx(20 + q * (1 / 4 + 1 / 10), rel=1e-6)


def test_coolant_chain_follows_inlet_and_centrifugal_term_is_instantaneous():
    net = physics.load_network("motorized_spindle_s3", apply_mechanisms=False)
    scen = scenarios.blocks([scenarios.Block(0.5), scenarios.Block(2, 6000)], 60.0,
                            ambient=scenarios.constant(22.0), coolant=scenarios.constant(18.0))
    res = physics.simulate(net, scen)
    T0 = res.temperatures.iloc[0]
    assert T0["jacket_front"] < T0["jacket_rear"] < 22.0  # warmed along the stream by the room
    net_c = net.replace(physics.Output("z", "z", dict(net.output("z").sensitivity_um_K), centrifugal_um=2.0))
    res_c = physics.simulate(net_c, scen)
    diff = (res_c.displacements["z"] - res.displacements["z"]).to_numpy()
    expected = 2.0 * (scen.frame["speed_rpm"].to_numpy() / net.reference_speed_rpm) ** 2
    np.testing.assert_allclose(diff, expected, atol=1e-9)


def test_parameters_round_trip_through_with_values_and_spec():
    net = physics.load_network("vmc_spindle_s2")
    params = net.parameters()
    assert params["nodes.shaft.capacity_J_K"] == 4600.0
    assert params["outputs.z.sensitivity_um_K.shaft"] == 2.8
    changed = net.with_values({"nodes.shaft.capacity_J_K": 5000.0, "outputs.z.sensitivity_um_K.base": 0.5})
    assert changed.parameters()["nodes.shaft.capacity_J_K"] == 5000.0
    assert changed.output("z").sensitivity_um_K["base"] == 0.5
    assert net.parameters() == params  # the original is untouched
    again = physics.network_from_dict(physics.network_to_dict(changed))
    assert again.parameters() == changed.parameters()
    assert again.mechanisms == changed.mechanisms
    with pytest.raises(InputError, match="unknown parameter"):
        net.with_values({"nodes.shaft.mass_kg": 1.0})


def spec(**over):
    base = {"name": "t", "nodes": {"a": {"capacity_J_K": 100.0}},
            "edges": [{"a": "a", "b": "ambient", "G_W_K": 1.0}]}
    return {**base, **over}


@pytest.mark.parametrize("bad, match", [
    (spec(nodes={"a": {"capacity_J_K": 100.0, "mass": 3}}), "unknown field.*mass"),
    (spec(nodes={"a": {"group": "shaft"}}), "missing field 'capacity_J_K'"),
    (spec(nodes={"a": {"capacity_J_K": "lots"}}), "must be a number"),
    (spec(nodes={"a": {"capacity_J_K": -5.0}}), "capacity_J_K"),
    (spec(edges=[{"a": "a", "b": "nowhere", "G_W_K": 1.0}]), "unknown node 'nowhere'"),
    (spec(nodes={"a": {"capacity_J_K": 1.0}, "b": {"capacity_J_K": 1.0}}), r"no heat path"),
    (spec(sources={"s": {"type": "laser", "node": "a"}}), "type 'laser' is unknown"),
    (spec(outputs={"z": {"sensitivity_um_K": {"q": 1.0}}}), "unknown node 'q'"),
    (spec(sensors={"T": {"node": "a", "lag_s": -1}}), "lag_s"),
    (spec(colour="red"), "unknown network spec key"),
])
def test_spec_errors_name_the_problem(bad, match):
    with pytest.raises(InputError, match=match):
        physics.network_from_dict(bad, file="m.yaml")


def test_load_network_errors_and_names(tmp_path):
    assert {"demo_spindle", "turning_centre_s1", "vmc_spindle_s2", "motorized_spindle_s3"} <= set(
        physics.network_names())
    with pytest.raises(InputError, match="unknown network"):
        physics.load_network("no_such_machine")
    broken = tmp_path / "m.yaml"
    broken.write_text("nodes: [a: {", encoding="utf-8")
    with pytest.raises(InputError, match="not valid YAML"):
        physics.load_network(broken)
    good = tmp_path / "g.yaml"
    good.write_text(yaml.safe_dump(spec()), encoding="utf-8")
    assert physics.load_network(good).node_names == ["a"]
    schema = physics.schema()
    assert schema["node"]["capacity_J_K"]["unit"] == "J/K"
    assert schema["source:bearing"]["viscous_exponent"]["default"] == pytest.approx(5 / 3)


def test_scenarios_are_well_formed():
    fl = scenarios.fl_thermal(dt_s=15.0)
    assert len(fl) == 11114 and fl.hours == pytest.approx(46.308, abs=0.01)
    speeds = fl.frame["speed_rpm"].to_numpy()
    assert [float(s) for s in pd.unique(speeds[speeds > 0])] == [1250, 2500, 3750, 5000, 3500, 500, 1500, 4500]
    assert fl.frame["speed_rpm"].loc[24.2 * 3600:28.0 * 3600].eq(5000).all()
    s3 = scenarios.s3_programme()
    assert len(s3) == 4682
    inlet = s3.frame["coolant_inlet_degC"]
    assert inlet.min() == pytest.approx(19.5, abs=0.01) and inlet.max() == pytest.approx(20.5, abs=0.01)
    spectrum = np.abs(np.fft.rfft(inlet - inlet.mean()))
    period_min = len(inlet) / np.argmax(spectrum)
    assert 15 < period_min < 25  # the chiller's ≈ 20 min cycle
    day = scenarios.iso230_3_environmental()
    assert day.frame["ambient_degC"].max() - day.frame["ambient_degC"].min() == pytest.approx(10.0, abs=0.05)
    assert scenarios.s1_conditions().frame["condition"].nunique() == 4
    assert len(scenarios.s1_duty(dt_s=8 * 3600 / 420)) == 421
    with pytest.raises(InputError, match="unknown scenario"):
        scenarios.build("weekend")
    with pytest.raises(InputError, match="speed"):
        physics.Scenario(pd.DataFrame({"speed_rpm": [0.0, -1.0]}, index=[0.0, 1.0]))


def test_resampling_the_scenario_changes_only_the_grid():
    net = physics.load_network("demo_spindle")
    scen = scenarios.demo(dt_s=30.0)
    coarse = physics.simulate(net, scen, dt_s=60.0)
    fine = physics.simulate(net, scen)
    assert coarse.scenario.dt_s == 60.0
    common = coarse.temperatures.index.intersection(fine.temperatures.index)
    # Block edges fall on both grids; only the sampled ambient differs between the grids.
    np.testing.assert_allclose(coarse.temperatures.loc[common], fine.temperatures.loc[common], atol=0.02)


def test_network_specs_compose_from_hydra():
    from hydra import compose, initialize_config_module
    from omegaconf import OmegaConf

    with initialize_config_module(config_module="thermodrift.conf", version_base="1.3"):
        cfg = compose(config_name=None, overrides=["+network=vmc_spindle_s2"])
    net = physics.network_from_dict(OmegaConf.to_container(cfg.network, resolve=True))
    assert net.parameters() == physics.load_network("vmc_spindle_s2").parameters()
    assert [m["id"] for m in net.mechanisms] == ["centrifugal_growth", "preload_feedback", "slow_structural_mode"]
    baseline = physics.load_network("vmc_spindle_s2", skip_mechanisms=["slow_structural_mode"])
    assert [m["id"] for m in baseline.mechanisms] == ["centrifugal_growth", "preload_feedback"]
    assert "slow_structure" not in baseline.node_names


def test_one_displacement_formula_for_simulation_prediction_and_the_observer():
    """The compiled network's ``displacements`` is the one formula: what ``simulate`` and calibration's
    ``predict`` report, relative to the first row or to a reference state, with the centrifugal term."""
    from thermodrift.core.physics.calibration import StateObserver, predict
    from thermodrift.core.physics.integrate import CompiledNetwork

    assert not hasattr(CompiledNetwork, "outputs") and not hasattr(StateObserver, "displacements")
    net = two_node().replace(Output("z", "z", {"a": 2.0, "b": 1.0}, centrifugal_um=0.5))
    scen = scenarios.blocks([scenarios.Block(1.0, N_REF), scenarios.Block(1.0, N_REF / 2)], 60.0,
                            ambient=scenarios.constant(20.0))
    comp = CompiledNetwork(net)
    X = comp.trajectory(scen)
    speed = scen.frame["speed_rpm"].to_numpy()
    Y = comp.displacements(X, speed)
    r2 = (speed / N_REF) ** 2
    np.testing.assert_allclose(Y[:, 0], (X - X[0]) @ [2.0, 1.0] + 0.5 * r2, atol=1e-12)
    np.testing.assert_allclose(physics.simulate(net, scen).displacements["z"].to_numpy(), Y[:, 0], atol=1e-9)
    net_s = dataclasses.replace(net, sensors=(physics.DisplacementSensor("d", "z", noise_um=0.0),))
    readings, states = predict(net_s, scen, reference=X[0] + 1.0)
    np.testing.assert_allclose(readings["d"].to_numpy(), Y[:, 0] - 3.0, atol=1e-9)
    np.testing.assert_allclose(comp.displacements(X[5], speed[5], X[0])[0], Y[5], atol=1e-12)
