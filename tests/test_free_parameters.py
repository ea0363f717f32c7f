"""Free parameters: one type for calibration and mechanisms, mapped onto the network by factor and offset."""

from __future__ import annotations

import math

import pytest

from thermodrift.core import registry
from thermodrift.core.errors import InputError
from thermodrift.core.physics import calibration, mechanisms
from thermodrift.core.physics.calibration import FreeParameter
from thermodrift.core.physics.spec import load_network


def test_mechanisms_declare_the_free_parameter_type_calibration_searches():
    assert not hasattr(mechanisms, "FreeParam")
    net = load_network("demo_spindle")
    for name in registry.names("mechanism"):
        cls = registry.get("mechanism", name).factory
        places = cls.places(net)
        if not places:  # the building RC library (and an outside mechanism) may have no place in a spindle
            assert name.startswith("building_") or registry.get("mechanism", name).origin != "thermodrift", name
            continue
        mech = cls(**places[0])
        _, free = mech.declare(net)
        assert free and all(type(fp) is calibration.FreeParameter for fp in free), name


def test_factor_and_offset_map_a_value_onto_every_path_and_back():
    fp = FreeParameter("tau_h", ("nodes.a.capacity_J_K", "nodes.b.capacity_J_K"), 2.0, 0.5, 24.0, "h",
                       factor=3600.0 * 4.0, offset=10.0)
    assert fp.network_value(2.0) == 28810.0 and fp.from_network(28810.0) == 2.0
    assert fp.path_values(2.0) == {"nodes.a.capacity_J_K": 28810.0, "nodes.b.capacity_J_K": 28810.0}
    assert fp.to_search(2.0) == pytest.approx(math.log(28810.0))
    assert fp.from_search(fp.to_search(2.0)) == pytest.approx(2.0)
    grouped = FreeParameter("G×", ("edges.a.G_W_K", "edges.b.G_W_K"), 1.0, 0.1, 10.0, "1", scales=(2.0, 5.0))
    assert grouped.path_values(3.0) == {"edges.a.G_W_K": 6.0, "edges.b.G_W_K": 15.0}


def test_a_shift_searched_on_the_network_scale_keeps_its_bounds_and_start():
    """A shift of −1 added to an exponent of 1.5 is a log parameter: the exponent, not the shift, stays positive."""
    shift = FreeParameter("exponent_shift", ("sources.s.viscous_exponent",), 0.5, -1.0, 1.5, "1", offset=1.5)
    on_net = shift.on_network_scale(2.0)  # a start above the bound is clipped into it
    assert (on_net.factor, on_net.offset, on_net.scale) == (1.0, 0.0, "log")
    assert on_net.low == pytest.approx(0.5) and on_net.low > 0.5 and on_net.high < 3.0
    assert on_net.value == on_net.high
    with pytest.raises(InputError, match="positive network value"):
        FreeParameter("exponent_shift", ("p",), 0.5, -2.0, 1.5, "1", offset=1.5)


@pytest.mark.parametrize("kwargs, match", [
    ({"scale": "cubic"}, "has scale 'cubic'"),
    ({"value": 50.0}, r"need 0 < low ≤ value ≤ high"),
    ({"factor": -1.0}, "factor must be positive"),
])
def test_bad_free_parameters_are_refused_when_made(kwargs, match):
    with pytest.raises(InputError, match=match):
        FreeParameter(**{"name": "g", "paths": ("edges.a.G_W_K",), "value": 1.0, "low": 0.1, "high": 10.0, **kwargs})
