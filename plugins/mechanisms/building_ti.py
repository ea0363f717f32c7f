"""``building_ti``: the interior state Ti, the one-state building model (an empty stochastic network becomes
Ci dTi = [(Ta − Ti)/Ria + Aw·Ps + Phi] dt + σi dW, measured as yTi = Ti + e)."""

from __future__ import annotations

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.stochastic.building import (BuildingMechanism, aperture, capacity, measurement,
                                                          replace, resistance, sigma)
from thermodrift.core.physics.stochastic.rc import RCNetwork


class BuildingTi(BuildingMechanism):
    id = "building_ti"
    summary = "the interior state Ti, the one-state building model"
    part = "Ti"
    drivers = ("ambient", "heating")
    parameters = (capacity("Ci", 1.0, "interior air, furniture and inner surfaces"),
                  resistance("Ria", 5.0, "interior to outdoor air"),
                  aperture("Aw", 5.0, "effective window area: solar gain into Ti"),
                  sigma("Ti", 0.2), measurement())
    signature = "the interior air follows outdoor air, sun and heating with one time constant"

    @classmethod
    def _applies(cls, net: RCNetwork) -> bool:
        return not net.states and net.has_input("ambient") and net.has_input("heating")

    def _extend(self, net: RCNetwork, p: dict[str, float]) -> RCNetwork:
        ta, phi = net.input_of("ambient"), net.input_of("heating")
        heat = (("Ti", phi, ""),)
        if net.has_input("solar_irradiance"):
            heat = (("Ti", net.input_of("solar_irradiance"), "Aw"),) + heat
        return replace(net, states=(("Ti", "Ci"),), noise=(("Ti", "sigma_ti"),), couplings=(("Ti", ta, "Ria"),),
                       heat=heat, outputs=(("yTi", "Ti", "sigma_y"),))


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", BuildingTi.id, BuildingTi)
