"""Every registered mechanism applies, moves the simulation in its documented direction, and switches off."""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest

from thermodrift.core import physics, registry
from thermodrift.core.errors import InputError
from thermodrift.core.physics import scenarios
from thermodrift.core.physics.scenarios import Block

MECHANISMS = ["ambient_coupling", "coolant_coupling", "cutting_heat", "speed_dependent_convection",
              "bearing_heat_law", "preload_feedback", "sensor_lag", "centrifugal_growth", "slow_structural_mode",
              "contact_resistance", "radiation", "axis_drive_heat", "thermal_tilt"]
H = 3600.0


@pytest.fixture(scope="module")
def reg():
    return registry.load()


@pytest.fixture(scope="module")
def base():
    return physics.load_network("demo_spindle")


# Idle, 1500 rpm, 6000 rpm, 6000 rpm cutting 3 kW (from 5.5 h), cool-down, axis motion with the spindle idle
# (from 10.5 h), at a constant 20 °C room and a chiller cycling around 20 °C.
RICH = scenarios.blocks([Block(0.5), Block(2, 1500), Block(1), Block(2, 6000), Block(2, 6000, cutting_power_W=3000),
                         Block(3), Block(2, 0, axis_velocity_mm_min=8000), Block(1)], 60.0,
                        ambient=scenarios.constant(20.0), coolant=scenarios.chiller_cycling(20.0, 0.5))


def sim(net, scen=RICH):
    return physics.simulate(net, scen)


def test_the_thirteen_mechanisms_are_registered_with_documented_parameters(reg):
    machine = [n for n in reg.names("mechanism")  # the built-in machine mechanisms: building RC library and
               if not n.startswith("building_") and reg.get("mechanism", n).origin == "thermodrift"]  # outside ones apart
    assert sorted(machine) == sorted(MECHANISMS)
    for name in MECHANISMS:
        cls = reg.get("mechanism", name).factory
        assert cls.id == name and cls.signature and cls.parameters
        doc = " ".join(importlib.import_module(cls.__module__).__doc__.split())
        assert "Residual signature" in doc
        for p in cls.parameters:
            assert p.low <= p.default <= p.high and p.low <= p.neutral <= p.high and p.unit
            assert p.name in doc


@pytest.mark.parametrize("name", MECHANISMS)
def test_mechanism_applies_changes_output_and_switches_off(reg, base, name):
    mech = reg.create("mechanism", name)
    ref = sim(base)
    on = mech.apply(base)
    assert on.mechanisms[-1]["id"] == name and base.mechanisms == ()
    scen = RICH
    measured_ref, measured_on = ref.measure(None), sim(on, scen).measure(None)
    assert np.max(np.abs(measured_on.to_numpy() - measured_ref.to_numpy())) > 0.05
    off = sim(mech.apply(base, **mech.neutral()))
    np.testing.assert_allclose(off.measure(None).to_numpy(), measured_ref.to_numpy(), atol=1e-8)
    with pytest.raises(InputError, match="outside"):
        mech.apply(base, **{mech.parameters[0].name: mech.parameters[0].high + 1})


def delta(reg, base, name, column, scen=RICH, kind="temperatures", **params):
    """(with − without) for one node temperature or output, plus the time axis in h."""
    ref, on = sim(base, scen), sim(reg.create("mechanism", name).apply(base, **params), scen)
    d = getattr(on, kind)[column] - getattr(ref, kind)[column]
    return d.to_numpy(), d.index.to_numpy() / H


def test_ambient_coupling_makes_the_structure_follow_the_room(reg, base):
    day = scenarios.iso230_3_environmental(hours=48.0, dt_s=300.0)
    room = day.frame["ambient_degC"].loc[24 * H:]
    ref = sim(base, day).temperatures["column"].loc[24 * H:]
    coupled = reg.create("mechanism", "ambient_coupling", nodes=["column"]).apply(base, G_W_K=20.0)
    on = sim(coupled, day).temperatures["column"].loc[24 * H:]
    lagging = lambda T: np.sqrt(np.mean((T - room) ** 2))  # noqa: E731
    assert lagging(on) < 0.75 * lagging(ref)
    assert on.std() > ref.std()


def test_coolant_coupling_cools_the_housing_at_speed(reg, base):
    d, t = delta(reg, base, "coolant_coupling", "housing")
    assert d[(t > 5) & (t < 7.5)].max() < -1.0


def test_cutting_heat_appears_only_once_cutting_starts(reg, base):
    d, t = delta(reg, base, "cutting_heat", "z", kind="displacements")
    assert np.all(np.abs(d[t <= 5.5]) < 1e-9)
    assert d[(t > 5.5) & (t <= 7.5)].max() > 0.5


def test_speed_dependent_convection_lowers_the_hot_steady_state(reg, base):
    d1500, t = delta(reg, base, "speed_dependent_convection", "shaft")
    at_1500, at_6000 = d1500[np.searchsorted(t, 2.5)], d1500[np.searchsorted(t, 5.5)]
    assert at_6000 < at_1500 < 0


def test_bearing_heat_law_shift_cools_the_low_speed_plateau(reg, base):
    d, t = delta(reg, base, "bearing_heat_law", "front_bearing", exponent_shift=0.5, viscosity_coeff_per_K=0.0)
    assert d[np.searchsorted(t, 2.5)] < -1.0            # n/n_ref = 0.25: heat × 0.25^0.5
    assert abs(d[np.searchsorted(t, 5.5)]) < 0.05 * abs(d[np.searchsorted(t, 2.5)]) + 0.2  # n_ref: unchanged


def test_preload_feedback_grows_super_linearly_with_speed(reg, base):
    d, t = delta(reg, base, "preload_feedback", "front_bearing", gain_W_K=3.0)
    low, high = d[np.searchsorted(t, 2.5)], d[np.searchsorted(t, 5.5)]
    assert high > 0 and high > 4 * low  # speed ratio 4, plus the larger shaft–housing difference


def test_sensor_lag_delays_readings_but_not_the_metal(reg, base):
    mech = reg.create("mechanism", "sensor_lag")
    ref, on = sim(base), sim(mech.apply(base, lag_s=600.0))
    assert np.array_equal(on.temperatures.to_numpy(), ref.temperatures.to_numpy())
    lag = (on.measure(None) - ref.measure(None))["T_front_bearing"]
    t = lag.index.to_numpy() / H
    assert lag[(t > 3.5) & (t < 4.0)].min() < -1.0   # warming: the reading trails
    assert lag[(t > 7.5) & (t < 8.0)].max() > 1.0    # cooling: the reading stays high
    assert (on.measure(None) - ref.measure(None))["T_ambient"].abs().max() == 0.0


def test_centrifugal_growth_is_an_instant_step_proportional_to_speed_squared(reg, base):
    d, t = delta(reg, base, "centrifugal_growth", "z", kind="displacements", um_at_ref=1.5)
    n = RICH.frame["speed_rpm"].to_numpy()
    np.testing.assert_allclose(d, 1.5 * (n / base.reference_speed_rpm) ** 2, atol=1e-9)


def test_slow_structural_mode_gives_cool_down_overshoot(reg, base):
    long_run = scenarios.iso230_3_constant_speed(6000, hours_on=8, hours_off=10, dt_s=120.0)
    ref = sim(base, long_run).displacements["z"]
    on = sim(reg.create("mechanism", "slow_structural_mode").apply(base, gain_um_K=-6.0, tau_h=4.0),
             long_run).displacements["z"]
    assert on.loc[12 * H:].min() < ref.loc[12 * H:].min() - 3.0   # the cool-down overshoots past the start
    run = on.loc[:8.2 * H]
    assert run.idxmax() / H < 6 and run.iloc[-1] < run.max() - 2.0  # and the run itself peaks and falls back


def test_contact_resistance_steepens_the_joint_gradient(reg, base):
    ref, on = sim(base), sim(reg.create("mechanism", "contact_resistance").apply(base, R_K_W=0.5))
    gradient = lambda r: (r.temperatures["housing"] - r.temperatures["column"]).max()  # noqa: E731
    assert gradient(on) > 1.3 * gradient(ref)
    assert on.temperatures["column"].max() < ref.temperatures["column"].max()


def test_radiation_lowers_structure_temperatures(reg, base):
    d, _ = delta(reg, base, "radiation", "column")
    assert d.max() <= 1e-12 and d.min() < -0.1


def test_axis_drive_heat_drifts_the_axis_with_the_spindle_idle(reg, base):
    d, t = delta(reg, base, "axis_drive_heat", "x", kind="displacements")
    assert np.all(np.abs(d[t <= 10.5]) < 1e-9)
    assert d[(t > 10.5) & (t <= 12.5)].max() > 1.0


def test_thermal_tilt_follows_the_hot_minus_cold_difference(reg, base):
    ref, on = sim(base), sim(reg.create("mechanism", "thermal_tilt").apply(base, um_K=4.0))
    T = ref.temperatures
    expected = 4.0 * ((T["housing"] - T["housing"].iloc[0]) - (T["column"] - T["column"].iloc[0]))
    np.testing.assert_allclose(on.displacements["x"] - ref.displacements["x"], expected, atol=1e-9)
    np.testing.assert_allclose(on.displacements["z"], ref.displacements["z"], atol=1e-12)


def test_mechanism_options_and_errors(reg, base):
    with pytest.raises(InputError, match="unknown option"):
        reg.create("mechanism", "radiation", colour="black")
    with pytest.raises(InputError, match="unknown parameter"):
        reg.create("mechanism", "radiation").apply(base, temperature=3.0)
    with pytest.raises(InputError, match="no node"):
        reg.create("mechanism", "ambient_coupling", nodes=["nope"]).apply(base)
    two = reg.create("mechanism", "slow_structural_mode").apply(
        reg.create("mechanism", "slow_structural_mode").apply(base))
    assert {"slow_structure", "slow_structure_2"} <= set(two.node_names)
    physics.CompiledNetwork(two)  # still a valid network


def test_ambient_coupling_has_places_on_a_network_whose_every_node_is_a_bearing(reg, base):
    cls = reg.get("mechanism", "ambient_coupling").factory
    all_bearing = base.replace(*[dataclasses.replace(n, group="bearing") for n in base.nodes])
    places = cls.places(all_bearing)
    assert places and all(p["nodes"][0] in all_bearing.nodes_in("bearing") for p in places)
    coupled = cls(**places[0]).apply(all_bearing, G_W_K=5.0)
    assert len(coupled.edges) == len(all_bearing.edges) + 1


def test_preload_and_slow_mode_have_places_on_a_network_whose_measured_nodes_are_all_bearings(reg, base):
    # an auto network whose every sensor rises with the spindle: measured nodes "bearing", hidden ones "shaft"
    all_bearing = base.replace(*[dataclasses.replace(n, group="bearing") for n in base.nodes if n.group != "shaft"])
    for mid in ("preload_feedback", "slow_structural_mode"):
        cls = reg.get("mechanism", mid).factory
        places = cls.places(all_bearing)
        assert places and all(p["nodes"][0] in all_bearing.nodes_in("bearing") for p in places)
        for place in places:
            changed = cls(**place).apply(all_bearing, **{p.name: p.default for p in cls.parameters})
            on, off = sim(changed).measure(None).to_numpy(), sim(all_bearing).measure(None).to_numpy()
            assert np.max(np.abs(on - off)) > 0.05
    preload = reg.get("mechanism", "preload_feedback").factory
    assert all(p["cold"] == p["nodes"][0] for p in preload.places(all_bearing))  # the bearing's own housing reading
    assert all("cold" not in p for p in preload.places(base))  # with a housing node nothing changes


def test_centrifugal_growth_of_several_um_is_within_its_physical_bounds(reg, base):
    cls = reg.get("mechanism", "centrifugal_growth").factory
    _, free = cls(axes=["z"]).declare(base, um_at_ref=1.0)
    assert all(fp.low <= -8.7 and fp.high >= 8.7 for fp in free)  # large spindles near top speed reach that
    assert all(fp.high <= 20.0 for fp in free)
