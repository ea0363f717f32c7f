"""radiation — thermal radiation from painted castings to the surroundings, linearised.

Adds a radiation edge to ambient on each target node (default: structure, else housing nodes) with
G = 4εσT_m³A (T_m = ``mean_degC`` option), the area shared equally: ε = 0.9 gives ≈ 5.4 W/m²K at 25 °C,
comparable to free convection.

Parameters: ``emissivity`` = 0.9 [0, 1] (neutral 0), ``area_m2`` = 1.0 [0, 10] m².
Direction: lower steady temperatures of the radiating nodes; faster following of the ambient.
Residual signature when missing: ∝ εσ(T⁴ − T_a⁴), nearly linear in ΔT — usually not separable from convection
(ambient_coupling); a finder should say so rather than pick one.
"""

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, nodes_of,
                                                 target_nodes, unique_name)
from thermodrift.core.physics.network import Edge, radiation_conductance


class Radiation(Mechanism):
    id = "radiation"
    summary = "thermal radiation from painted castings to the surroundings, linearised"
    experiment = "a change of surface emissivity (paint or foil): thermally it is indistinguishable from convection"
    parameters = (
        Parameter("emissivity", 0.9, 0.0, 1.0, "1", 0.0, "surface emissivity (painted cast iron ≈ 0.9)"),
        Parameter("area_m2", 1.0, 0.0, 10.0, "m2", 1.0, "radiating area, shared by the nodes"),
    )
    options = {"nodes": None, "groups": ("structure", "housing"), "mean_degC": 25.0}
    signature = "∝ εσ(T⁴ − T_a⁴), nearly linear in ΔT; usually not separable from convection"
    laws = ("Stefan–Boltzmann exchange ∝ T⁴ − T_a⁴",)

    def _apply(self, network, p, o):
        nodes = target_nodes(network, self.id, o["nodes"], o["groups"])
        g = radiation_conductance(p["emissivity"], p["area_m2"] / len(nodes), float(o["mean_degC"]))
        names = [e.name for e in network.edges]
        edges = []
        for n in nodes:
            names.append(unique_name(names, f"{n}-ambient_radiation"))
            edges.append(Edge(names[-1], n, "ambient", g, kind="radiation"))
        return network.add(*edges)

    @classmethod
    def places(cls, network):
        return [{"nodes": [n]} for n in nodes_of(network, ("structure", "housing", "table", "motor"))] or [{}]

    def _declare(self, before, after, p, o):
        edges = added(before, after, "edges")
        per_unit = radiation_conductance(1.0, p["area_m2"] / len(edges), float(o["mean_degC"]))
        return [FreeParameter("emissivity", tuple(f"edges.{e.name}.G_W_K" for e in edges), p["emissivity"],
                          max(1e-3, p["emissivity"] * 1e-3), 1.0, "1", factor=per_unit)]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", Radiation.id, Radiation)
