"""``building_te``: the building envelope Te between the interior and outdoor air: Ce dTe = [(Ti − Te)/Rie +
(Ta − Te)/Rea] dt + σe dW; the interior then loses heat through the envelope only (its direct Ria goes)."""

from __future__ import annotations

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.stochastic.building import (BuildingMechanism, capacity, replace, resistance, sigma,
                                                          states_plus)
from thermodrift.core.physics.stochastic.rc import RCNetwork


class BuildingTe(BuildingMechanism):
    id = "building_te"
    summary = "the building envelope Te between the interior and the outdoor air"
    part = "Te"
    parameters = (capacity("Ce", 5.0, "building envelope"),
                  resistance("Rie", 1.0, "interior to envelope"),
                  resistance("Rea", 4.0, "envelope to outdoor air"),
                  sigma("Te", 0.2))
    signature = "a slow envelope between interior and outdoor air: two time constants in the interior's response"

    @classmethod
    def _applies(cls, net: RCNetwork) -> bool:
        return "Ti" in net.state_names and "Te" not in net.state_names

    def _extend(self, net: RCNetwork, p: dict[str, float]) -> RCNetwork:
        ta = net.input_of("ambient")
        couplings = tuple(c for c in net.couplings if c != ("Ti", ta, "Ria"))
        return replace(net, couplings=couplings + (("Ti", "Te", "Rie"), ("Te", ta, "Rea")),
                       **states_plus(net, "Te", "Ce", "sigma_te"))


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", BuildingTe.id, BuildingTe)
