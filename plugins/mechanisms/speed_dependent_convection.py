"""speed_dependent_convection — forced convection on rotating parts, h ∝ n^0.7 (3.75 ω^0.7 r^0.4).

Adds to each target node (default: shaft, else bearings) a convection edge to ambient that is zero at
standstill and ``G_rot_W_K``·(n/n_ref)^``exponent`` while running (shared equally by the nodes).

Parameters: ``G_rot_W_K`` = 3.0 [0, 50] W/K at the reference speed (neutral 0), ``exponent`` = 0.7 [0.4, 1.0].
Direction: lower steady temperatures at high speed; warm-up faster than cool-down (τ_heat < τ_cool).
Residual signature when missing: steady state over-predicted at high n; cool-down τ ≠ warm-up τ. Test: τ_heat vs
τ_cool per segment.
"""

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, log_bounds,
                                                 nodes_of, target_nodes, unique_name)
from thermodrift.core.physics.network import Edge


class SpeedDependentConvection(Mechanism):
    id = "speed_dependent_convection"
    summary = "forced convection on rotating parts, h ∝ n^0.7 (3.75 ω^0.7 r^0.4)"
    experiment = "warm-up and cool-down to steady state at several speed plateaus"
    shapes = ({"exponent": 0.7},)
    parameters = (
        Parameter("G_rot_W_K", 3.0, 0.0, 50.0, "W/K", 0.0, "forced-convection conductance at the reference speed"),
        Parameter("exponent", 0.7, 0.4, 1.0, "1", 0.7, "speed exponent of h"),
    )
    options = {"nodes": None, "groups": ("shaft", "bearing")}
    drivers = ("speed",)
    signature = "steady state over-predicted at high n; cool-down τ differs from warm-up τ"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "speed_convection", "taus_s": (600.0, 1800.0, 7200.0), "sign": 1,
                       "drift_sense": True}
    laws = ("film coefficient as a power of speed",)

    def _apply(self, network, p, o):
        nodes = target_nodes(network, self.id, o["nodes"], o["groups"])
        names = [e.name for e in network.edges]
        edges = []
        for n in nodes:
            names.append(unique_name(names, f"{n}-ambient_forced"))
            edges.append(Edge(names[-1], n, "ambient", 0.0, kind="convection",
                              G_rot_W_K=p["G_rot_W_K"] / len(nodes), rot_exponent=p["exponent"]))
        return network.add(*edges)

    @classmethod
    def places(cls, network):
        return [{"nodes": [n]} for n in nodes_of(network, ("shaft", "bearing", "motor"))] or [{}]

    def _declare(self, before, after, p, o):
        edges = added(before, after, "edges")
        return [FreeParameter("G_rot_W_K", tuple(f"edges.{e.name}.G_rot_W_K" for e in edges), p["G_rot_W_K"],
                          *log_bounds(self.parameters[0], p["G_rot_W_K"]), "W/K", factor=1.0 / len(edges))]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", SpeedDependentConvection.id, SpeedDependentConvection)
