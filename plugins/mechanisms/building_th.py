"""``building_th``: the heater Th: the heating enters Th (Ch dTh = [(Ti − Th)/Rih + Phi] dt + σh dW), which
heats the interior through Rih."""

from __future__ import annotations

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.stochastic.building import (BuildingMechanism, capacity, replace, resistance, sigma,
                                                          states_plus)
from thermodrift.core.physics.stochastic.rc import RCNetwork


class BuildingTh(BuildingMechanism):
    id = "building_th"
    summary = "the heater Th, a capacity the heating enters before the interior air"
    part = "Th"
    drivers = ("heating",)
    parameters = (capacity("Ch", 0.2, "heater and its water"),
                  resistance("Rih", 0.5, "heater to interior"),
                  sigma("Th", 0.5))
    signature = "the interior answers the heating with a lag: heat passes through the heater's own capacity"

    @classmethod
    def _applies(cls, net: RCNetwork) -> bool:
        return "Ti" in net.state_names and "Th" not in net.state_names

    def _extend(self, net: RCNetwork, p: dict[str, float]) -> RCNetwork:
        phi = net.input_of("heating")
        heat = tuple(("Th", q, g) if (s, q) == ("Ti", phi) else (s, q, g) for s, q, g in net.heat)
        return replace(net, heat=heat, couplings=net.couplings + (("Ti", "Th", "Rih"),),
                       **states_plus(net, "Th", "Ch", "sigma_th"))


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", BuildingTh.id, BuildingTh)
