"""``building_ts``: the sensor Ts, a small capacity Cs exchanging with the interior through Ris
(Cs dTs = (Ti − Ts)/Ris dt + σs dW); the measurement reads Ts instead of Ti."""

from __future__ import annotations

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.stochastic.building import (BuildingMechanism, capacity, replace, resistance, sigma,
                                                          states_plus)
from thermodrift.core.physics.stochastic.rc import RCNetwork


class BuildingTs(BuildingMechanism):
    id = "building_ts"
    summary = "the sensor Ts, a small capacity exchanging with the interior through Ris"
    part = "Ts"
    parameters = (capacity("Cs", 0.05, "temperature sensor and what it is mounted on"),
                  resistance("Ris", 0.5, "interior air to sensor"),
                  sigma("Ts", 0.1))
    signature = "the measured temperature lags the interior air: the sensor has its own capacity"

    @classmethod
    def _applies(cls, net: RCNetwork) -> bool:
        return "Ti" in net.state_names and "Ts" not in net.state_names

    def _extend(self, net: RCNetwork, p: dict[str, float]) -> RCNetwork:
        outputs = tuple((o, "Ts" if s == "Ti" else s, r) for o, s, r in net.outputs)
        return replace(net, outputs=outputs, couplings=net.couplings + (("Ti", "Ts", "Ris"),),
                       **states_plus(net, "Ts", "Cs", "sigma_ts"))


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", BuildingTs.id, BuildingTs)
