"""``building_tm``: the thermal medium Tm (inner walls, floor): Cm dTm = (Ti − Tm)/Rim dt + σm dW, exchanging
with the interior through Rim."""

from __future__ import annotations

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.stochastic.building import (BuildingMechanism, capacity, replace, resistance, sigma,
                                                          states_plus)
from thermodrift.core.physics.stochastic.rc import RCNetwork


class BuildingTm(BuildingMechanism):
    id = "building_tm"
    summary = "the thermal medium Tm (inner walls, floor) exchanging with the interior through Rim"
    part = "Tm"
    parameters = (capacity("Cm", 10.0, "thermal medium: inner walls, floor, furniture mass"),
                  resistance("Rim", 0.5, "interior air to medium"),
                  sigma("Tm", 0.1))
    signature = "stored heat returns to the interior air after heating stops: a slow mass coupled to Ti only"

    @classmethod
    def _applies(cls, net: RCNetwork) -> bool:
        return "Ti" in net.state_names and "Tm" not in net.state_names

    def _extend(self, net: RCNetwork, p: dict[str, float]) -> RCNetwork:
        return replace(net, couplings=net.couplings + (("Ti", "Tm", "Rim"),),
                       **states_plus(net, "Tm", "Cm", "sigma_tm"))


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", BuildingTm.id, BuildingTm)
