"""Contract checks for mechanisms (``thermodrift.core.physics.Mechanism``), run on a small reference network.

A mechanism must: name a residual signature and driver roles that exist; declare, at every place it offers,
free parameters whose paths exist in the applied network and hold the declared start values, with bounds
inside the network fields' physical limits; leave the simulation unchanged at its neutral values; say why
a recording whose driver channel is missing or constant cannot drive it; and, where it explains a network without
a place for it (``unplaced``), do so in the report's words.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pandas as pd

from thermodrift.testing.estimator_checks import Factory

_MAX_PLACES = 4


@lru_cache(maxsize=1)
def _network():
    from thermodrift.core.physics.spec import network_from_dict

    spec = {"name": "mechanism_check", "reference_speed_rpm": 6000,
            "nodes": {"bearing": {"capacity_J_K": 1500, "group": "bearing"},
                      "shaft": {"capacity_J_K": 3700, "group": "shaft"},
                      "motor": {"capacity_J_K": 8000, "group": "motor"},
                      "housing": {"capacity_J_K": 18000, "group": "housing"},
                      "column": {"capacity_J_K": 150000, "group": "structure"}},
            "edges": [{"a": "bearing", "b": "shaft", "G_W_K": 4.0}, {"a": "bearing", "b": "housing", "G_W_K": 6.0},
                      {"a": "motor", "b": "shaft", "G_W_K": 8.0, "kind": "contact"},
                      {"a": "housing", "b": "column", "G_W_K": 12.0, "kind": "contact"},
                      {"a": "shaft", "b": "ambient", "G_W_K": 0.8, "kind": "convection"},
                      {"a": "housing", "b": "ambient", "G_W_K": 5.0, "kind": "convection"},
                      {"a": "column", "b": "ambient", "G_W_K": 18.0, "kind": "convection"}],
            "sources": {"bearing": {"type": "bearing", "node": "bearing", "viscous_W": 110, "load_W": 30},
                        "motor": {"type": "motor", "split": {"motor": 1.0}, "no_load_W": 80}},
            "outputs": {"z": {"axis": "z", "sensitivity_um_K": {"shaft": 6.0, "housing": 1.0, "column": 4.0}},
                        "x": {"axis": "x", "sensitivity_um_K": {"column": 2.0}}},
            "sensors": {"T_bearing": {"node": "bearing", "lag_s": 20}, "T_housing": {"node": "housing"},
                        "T_column": {"node": "column"}, "T_amb": {"node": "ambient", "role": "ambient"},
                        "disp_z": {"output": "z"}, "disp_x": {"output": "x"}}}
    return network_from_dict(spec, apply_mechanisms=False)


@lru_cache(maxsize=1)
def _scenario():
    from thermodrift.core.physics import scenarios
    from thermodrift.core.physics.scenarios import Block

    return scenarios.blocks([Block(0.5), Block(2, 3000), Block(1, 6000, cutting_power_W=2000), Block(1),
                             Block(1, 0, axis_velocity_mm_min=6000)], 120.0, ambient=scenarios.daily_cycle(),
                            coolant=scenarios.chiller_cycling())


def _outputs(net) -> np.ndarray:
    from thermodrift.core.physics.calibration import predict

    return predict(net, _scenario())[0].to_numpy()


def check_signature_and_drivers(factory: Factory, params: dict) -> None:
    """``signature`` is a sentence, every driver is a recording role and ``laws`` is a tuple of named laws."""
    from thermodrift.core.recording import ROLES

    assert isinstance(factory.signature, str) and len(factory.signature) > 10, "signature must describe the residual"
    bad = [d for d in factory.drivers if d not in ROLES]
    assert not bad, f"drivers {bad} are not recording roles ({', '.join(ROLES)})"
    assert isinstance(factory.laws, tuple) and all(isinstance(x, str) and x for x in factory.laws), \
        "laws must be a tuple of law names"


def check_declares_free_parameters(factory: Factory, params: dict) -> None:
    """At each place (up to four) ``declare`` returns free parameters whose paths hold their start values."""
    net = _network()
    places = factory.places(net)
    assert isinstance(places, list), "places(network) must return a list of option dicts"
    for options in places[:_MAX_PLACES]:
        mech = factory(**{**params, **options})
        after, free = mech.declare(net)
        assert free, f"declare() at {options} introduced no free parameter"
        values = after.parameters()
        for fp in free:
            for path in fp.paths:
                assert abs(values[path] - fp.network_value(fp.value)) <= 1e-9 * max(1.0, abs(values[path])), (
                    f"{fp.name} at {options}: {path} is {values[path]:g}, the declaration says "
                    f"{fp.network_value(fp.value):g}")


def check_neutral_changes_nothing(factory: Factory, params: dict) -> None:
    """At its neutral values the mechanism leaves every simulated sensor reading unchanged."""
    net = _network()
    for options in factory.places(net)[:_MAX_PLACES]:
        mech = factory(**{**params, **options})
        diff = np.abs(_outputs(mech.apply(net, **mech.neutral())) - _outputs(net)).max()
        assert diff < 1e-6, f"neutral values at {options} change the readings by {diff:g}"


def check_missing_drivers_named(factory: Factory, params: dict) -> None:
    """A recording without (or with a constant) driver channel gets a reason; a varying one gets None."""
    from thermodrift.core.recording import Channel, Recording

    t = np.arange(50) * 60.0
    unit_of = {"speed": "rpm", "cutting_power": "W", "axis_velocity": "mm_min"}
    step = np.r_[np.zeros(25), np.ones(25)]
    varying = {f"drv_{r}": (step * 1000.0, Channel(f"drv_{r}", r, unit_of.get(r, "degC"), {})) for r in factory.drivers}
    for role in factory.drivers:
        others = {k: v for k, v in varying.items() if k != f"drv_{role}"}
        base = {**others, "T": (np.linspace(20, 25, 50), Channel("T", "temperature", "degC", {})),
                "d": (np.linspace(0, 5, 50), Channel("d", "displacement", "um", {}))}
        if role != "speed":
            base["n"] = (np.r_[np.zeros(25), np.full(25, 3000.0)], Channel("n", "speed", "rpm", {}))

        def rec(extra):
            cols = {**base, **extra}
            return Recording(pd.DataFrame({k: v[0] for k, v in cols.items()}, index=pd.Index(t, name="time_s")),
                             {k: v[1] for k, v in cols.items()})
        unit = unit_of.get(role, "degC")
        assert factory.missing_drivers(rec({})), f"no reason given for a recording without a {role} channel"
        flat = {"drv": (np.full(50, 1.0), Channel("drv", role, unit, {}))}
        assert factory.missing_drivers(rec(flat)), f"no reason given for a constant {role} channel"
        reason = factory.missing_drivers(rec({f"drv_{role}": varying[f"drv_{role}"]}))
        assert reason is None, f"varying driver channels were refused: {reason}"


def check_unplaced_reason(factory: Factory, params: dict) -> None:
    """``unplaced(network)`` is None, or, where ``places`` is empty, a reason the diagnosis can report as it is:
    "skipped: …" or "nested in the baseline: …" (on the reference network and on the same network with every node
    but the shaft labelled a bearing, as an ``auto`` network whose every sensor rises with the spindle is)."""
    import dataclasses

    net = _network()
    all_bearing = net.replace(*[dataclasses.replace(n, group="bearing") for n in net.nodes if n.group != "shaft"])
    for network in (net, all_bearing):
        why = factory.unplaced(network)
        if why is None:
            continue
        assert not factory.places(network), f"unplaced() gives a reason where places() has some: {why}"
        assert isinstance(why, str) and why.startswith(("skipped: ", "nested in the baseline: ")), (
            f"unplaced() must start 'skipped: ' or 'nested in the baseline: ', not {why!r}")


def check_report_metadata(factory: Factory, params: dict) -> None:
    """What the finder reports and screens, declared on the mechanism: a one-line ``summary``; an
    ``experiment`` (text, may be empty); ``shapes``, a tuple of parameter-value dicts inside the bounds; ``signed``
    a bool."""
    summary = getattr(factory, "summary", "")
    assert isinstance(summary, str) and summary.strip() and "\n" not in summary, (
        "set summary: one line on the physics it adds, in the report's words")
    assert isinstance(getattr(factory, "experiment", ""), str), "experiment must be text"
    assert isinstance(getattr(factory, "signed", False), bool), "signed must be True or False"
    shapes = getattr(factory, "shapes", ())
    assert isinstance(shapes, tuple), f"shapes must be a tuple of dicts, got {type(shapes).__name__}"
    bounds = {p.name: (p.low, p.high) for p in factory.parameters}
    for shape in shapes:
        assert isinstance(shape, dict) and shape, f"a shape must be a non-empty dict of parameter values: {shape!r}"
        for name, value in shape.items():
            assert name in bounds, f"shape {shape} names {name!r}, not a parameter ({', '.join(bounds)})"
            low, high = bounds[name]
            assert low <= value <= high, f"shape {shape}: {name} = {value} outside [{low}, {high}]"


MECHANISM_CHECKS = (check_report_metadata, check_signature_and_drivers, check_declares_free_parameters,
                    check_neutral_changes_nothing, check_missing_drivers_named, check_unplaced_reason)
