"""coolant_coupling — a cooling jacket fed by the chiller (advection from the coolant inlet).

Adds a fluid node ``coolant_jacket`` (group coolant, ``capacity_J_K`` option) fed by the ``coolant`` inlet
boundary with ṁc_p and joined to the target nodes (default: motor, else housing) by ``G_W_K``.

Parameters: ``G_W_K`` = 40 [0, 500] W/K (neutral 0), ``mdot_cp_W_K`` = 280 [1, 2000] W/K (4 L/min of water).
Direction: lower temperatures of the target nodes at speed; the chiller's on/off cycle (5–30 min) appears,
phase-lagged, in the temperatures and displacements.
Residual signature when missing: periodic at the chiller period, lagged to the coolant inlet; steps when the
coolant switches. Test: coherence with the coolant inlet at its period.
"""

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, log_bounds,
                                                 nodes_of, target_nodes, unique_name)
from thermodrift.core.physics.network import Advection, Edge, Node


class CoolantCoupling(Mechanism):
    id = "coolant_coupling"
    summary = "a cooling jacket fed by the chiller (advection from the coolant inlet)"
    experiment = "chiller cycling with the spindle stopped"
    parameters = (
        Parameter("G_W_K", 40.0, 0.0, 500.0, "W/K", 0.0, "jacket–structure conductance, shared by the nodes"),
        Parameter("mdot_cp_W_K", 280.0, 1.0, 2000.0, "W/K", 280.0, "coolant mass flow × specific heat"),
    )
    options = {"nodes": None, "groups": ("motor", "housing"), "capacity_J_K": 2000.0}
    drivers = ("coolant_inlet",)
    signature = "periodic at the chiller period, phase-lagged to the coolant inlet; steps when the coolant switches"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "coolant_inlet", "taus_s": (300.0, 1200.0, 3600.0), "sign": 1}

    def _apply(self, network, p, o):
        nodes = target_nodes(network, self.id, o["nodes"], o["groups"])
        jacket = unique_name(network.node_names, "coolant_jacket")
        names = [e.name for e in network.edges]
        edges = []
        for n in nodes:
            names.append(unique_name(names, f"{jacket}-{n}"))
            edges.append(Edge(names[-1], jacket, n, p["G_W_K"] / len(nodes), kind="convection"))
        inflow = Advection(unique_name([a.name for a in network.advections], f"coolant->{jacket}"), "coolant",
                           jacket, p["mdot_cp_W_K"])
        return network.add(Node(jacket, float(o["capacity_J_K"]), "coolant"), inflow, *edges)

    @classmethod
    def places(cls, network):
        return [{"nodes": [n]} for n in nodes_of(network, ("motor", "housing", "bearing", "shaft"))] or [{}]

    def _declare(self, before, after, p, o):
        edges = added(before, after, "edges")
        flow = added(before, after, "advections")[0]
        return [FreeParameter("G_W_K", tuple(f"edges.{e.name}.G_W_K" for e in edges), p["G_W_K"],
                          *log_bounds(self.parameters[0], p["G_W_K"]), "W/K", factor=1.0 / len(edges)),
                FreeParameter("mdot_cp_W_K", (f"advections.{flow.name}.mdot_cp_W_K",), p["mdot_cp_W_K"], 1.0, 2000.0,
                          "W/K")]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", CoolantCoupling.id, CoolantCoupling)
