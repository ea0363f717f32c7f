"""``building_aeria``: with an envelope Te, the envelope's solar aperture Ae (Ae·Ps into Te) plus a direct
interior–ambient resistance Ria (air leakage and windows beside the envelope)."""

from __future__ import annotations

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.stochastic.building import (AERIA, BuildingMechanism, aperture, replace,
                                                          resistance)
from thermodrift.core.physics.stochastic.rc import RCNetwork


class BuildingAeRia(BuildingMechanism):
    id = "building_aeria"
    summary = "the envelope's solar aperture Ae (solar gain into the envelope) plus a direct gain"
    part = AERIA
    drivers = ("solar_irradiance",)
    parameters = (aperture("Ae", 5.0, "effective solar aperture of the envelope"),
                  resistance("Ria", 20.0, "interior to outdoor air beside the envelope"))
    signature = "the envelope warms in the sun and some heat leaves the interior directly, not through the envelope"

    @classmethod
    def _applies(cls, net: RCNetwork) -> bool:
        return "Te" in net.state_names and not any(m["id"] == cls.id for m in net.mechanisms)

    def _extend(self, net: RCNetwork, p: dict[str, float]) -> RCNetwork:
        heat = net.heat
        if net.has_input("solar_irradiance"):
            heat = heat + (("Te", net.input_of("solar_irradiance"), "Ae"),)
        return replace(net, heat=heat, couplings=net.couplings + (("Ti", net.input_of("ambient"), "Ria"),))


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", BuildingAeRia.id, BuildingAeRia)
