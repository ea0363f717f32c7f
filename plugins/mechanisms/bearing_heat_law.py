"""bearing_heat_law — the bearings' heat follows another speed law than the network assumes.

Shifts the viscous speed exponent of every bearing source (heat at the reference speed unchanged) and adds a
viscosity–temperature dependence (viscous heat falls by γ per K as the oil warms). A network that assumed
heat ∝ n misses the Palmgren n^(5/3) viscous law with ``exponent_shift`` = +2/3.

Parameters: ``exponent_shift`` = +0.667 [−1, 1.5] (neutral 0), ``viscosity_coeff_per_K`` = 0.01 [0, 0.04] 1/K
(neutral 0).
Direction: a positive shift lowers the heat below the reference speed (steady ΔT across plateaus grows faster
with n); γ > 0 lowers the heat as the bearings warm (a flatter warm-up).
Residual signature when missing: steady ΔT vs n across plateaus follows another power law (n vs n^(5/3)).
Test: fit the exponent across speed levels.
"""

import dataclasses

from thermodrift.core.errors import InputError
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import FreeParameter, Mechanism, Parameter
from thermodrift.core.physics.network import BearingSource


class BearingHeatLaw(Mechanism):
    id = "bearing_heat_law"
    summary = "the bearings' heat follows another speed law than the network assumes"
    experiment = "speed plateaus at four or more levels, each to steady state"
    shapes = ({"exponent_shift": 0.5, "viscosity_coeff_per_K": 0.0},
              {"exponent_shift": -0.5, "viscosity_coeff_per_K": 0.0},
              {"exponent_shift": 0.0, "viscosity_coeff_per_K": 0.01})
    signed = True  # a negative fitted amplitude is still physical
    parameters = (
        Parameter("exponent_shift", 2 / 3, -1.0, 1.5, "1", 0.0, "added to the viscous speed exponent"),
        Parameter("viscosity_coeff_per_K", 0.01, 0.0, 0.04, "1/K", 0.0, "added relative viscous-heat fall per K"),
    )
    options = {"sources": None}
    drivers = ("speed",)
    signature = "steady ΔT vs n across plateaus follows another power law (n vs n^(5/3))"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "speed_power", "exponents": (0.75, 3.0), "taus_s": (600.0, 1800.0, 7200.0)}
    laws = ("friction heat as a power of speed", "oil viscosity falling with temperature")

    def _apply(self, network, p, o):
        chosen = o["sources"]
        bearings = [s for s in network.sources if isinstance(s, BearingSource) and (not chosen or s.name in chosen)]
        if not bearings:
            raise InputError(f"mechanism {self.id!r}: network {network.name!r} has no bearing source")
        return network.replace(*[dataclasses.replace(
            s, viscous_exponent=max(0.0, s.viscous_exponent + p["exponent_shift"]),
            viscosity_coeff_per_K=s.viscosity_coeff_per_K + p["viscosity_coeff_per_K"]) for s in bearings])

    @classmethod
    def places(cls, network):
        return [{"sources": [s.name]} for s in network.sources if isinstance(s, BearingSource)] or [{}]

    def _declare(self, before, after, p, o):
        # One place is one bearing source, so both parameters map onto one path each.
        old = next(s for s in before.sources if isinstance(s, BearingSource)
                   and (not o["sources"] or s.name in o["sources"]))
        base = f"sources.{old.name}"
        shift_low = max(-1.0, 0.05 - old.viscous_exponent)
        gamma_high = min(0.04, 0.05 - old.viscosity_coeff_per_K)
        return [FreeParameter("exponent_shift", (f"{base}.viscous_exponent",), p["exponent_shift"], shift_low, 1.5, "1",
                          offset=old.viscous_exponent),
                FreeParameter("viscosity_coeff_per_K", (f"{base}.viscosity_coeff_per_K",), p["viscosity_coeff_per_K"],
                          max(1e-4, p["viscosity_coeff_per_K"] * 1e-3), max(gamma_high, p["viscosity_coeff_per_K"]),
                          "1/K", offset=old.viscosity_coeff_per_K)]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", BearingHeatLaw.id, BearingHeatLaw)
