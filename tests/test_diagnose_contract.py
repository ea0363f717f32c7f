"""The mechanism contract: declared free parameters, places, driver roles, bounds against the network's limits,
and a conformance check that catches a mechanism breaking it."""

from __future__ import annotations

import dataclasses

import pytest

from thermodrift.core import registry
from thermodrift.core.errors import InputError
from thermodrift.core.physics import load_network
from thermodrift.core.physics.mechanisms import FreeParameter, Mechanism, Parameter, check_free
from thermodrift.testing import ConformanceError, check_mechanism

REG = registry.load()


def test_cutting_heat_declares_its_fraction_at_each_place():
    net = load_network("demo_spindle")
    cls = REG.get("mechanism", "cutting_heat").factory
    places = cls.places(net)
    assert {p["nodes"][0] for p in places} >= {"front_bearing", "shaft", "housing"}
    after, free = cls(**places[0]).declare(net, fraction=0.05)
    (fp,) = free
    assert fp.name == "fraction" and fp.scale == "log" and fp.value == 0.05 and fp.low > 0
    assert after.parameters()[fp.paths[0]] == pytest.approx(0.05)
    assert cls.drivers == ("cutting_power",)


def test_bounds_outside_the_network_field_limits_are_refused():
    net = REG.create("mechanism", "cutting_heat").apply(load_network("demo_spindle"))
    path = next(p for p in net.parameters() if p.endswith(".fraction"))
    with pytest.raises(InputError, match="outside its limits"):
        check_free(net, [FreeParameter("fraction", (path,), 0.5, 0.1, 2.28, "1")], "cutting_heat")
    with pytest.raises(InputError, match="has no parameter"):
        check_free(net, [FreeParameter("g", ("edges.nope.G_W_K",), 1.0, 0.1, 2.0, "W/K")], "x")


def test_every_registered_mechanism_passes_the_contract():
    for name in REG.names("mechanism"):
        check_mechanism(REG.get("mechanism", name).factory)


class _Broken(Mechanism):
    """Declares a parameter path it never sets, needs an unknown driver role, and is not neutral."""

    id = "broken"
    parameters = (Parameter("G_W_K", 3.0, 0.0, 10.0, "W/K", 0.0),)
    drivers = ("weather",)
    signature = "a residual nobody can name"

    def _apply(self, network, p, o):
        e = network.edges[0]
        return network.replace(dataclasses.replace(e, G_W_K=e.G_W_K + 1.0))

    def _declare(self, before, after, p, o):
        e = after.edges[0]
        return [FreeParameter("G_W_K", (f"edges.{e.name}.G_W_K",), p["G_W_K"], 0.1, 10.0, "W/K")]

    @classmethod
    def unplaced(cls, network):
        return "it would not fit here"  # a reason where it has places, and not in the report's words


def test_the_mechanism_checks_catch_a_broken_mechanism():
    with pytest.raises(ConformanceError) as err:
        check_mechanism(_Broken)
    text = str(err.value)
    assert "check_signature_and_drivers" in text and "check_neutral_changes_nothing" in text
    assert "check_declares_free_parameters" in text and "check_unplaced_reason" in text
