"""ambient_coupling — structure exchanging heat with the room air (extra convection to ambient).

Adds a convection edge to ``ambient`` on each target node (default: the structure nodes, else the housing;
places: the structure, housing, table and motor nodes, else the bearing nodes),
sharing ``G_W_K`` equally.

Parameters: ``G_W_K`` = 3.0 [0, 50] W/K (neutral 0).
Direction: the target nodes and the displacement channels follow the ambient temperature more closely and
with less lag; with the spindle stopped the drift tracks the daily cycle.
Residual signature when missing: present with the spindle stopped; follows the first-order-lagged ambient
(τ of hours); 24 h peak; same sign on the structural channels. Test: regress on lagged ambient, spindle-off
windows.
"""

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, log_bounds,
                                                 nodes_of, target_nodes, unique_name)
from thermodrift.core.physics.network import Edge


class AmbientCoupling(Mechanism):
    id = "ambient_coupling"
    summary = "structure exchanging heat with the room air (extra convection to ambient)"
    experiment = "a spindle-off soak over a full daily ambient cycle"
    parameters = (Parameter("G_W_K", 3.0, 0.0, 50.0, "W/K", 0.0, "extra conductance to ambient, shared by the nodes"),)
    options = {"nodes": None, "groups": ("structure", "housing")}
    drivers = ("ambient",)
    signature = "present with the spindle stopped; follows lagged ambient (τ hours); 24 h peak; same sign on structure"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "ambient", "taus_s": (1800.0, 7200.0, 28800.0), "sign": 1}

    def _apply(self, network, p, o):
        nodes = target_nodes(network, self.id, o["nodes"], o["groups"])
        names = [e.name for e in network.edges]
        edges = []
        for n in nodes:
            names.append(unique_name(names, f"{n}-ambient_coupling"))
            edges.append(Edge(names[-1], n, "ambient", p["G_W_K"] / len(nodes), kind="convection"))
        return network.add(*edges)

    @classmethod
    def places(cls, network):
        # a network whose every node rises with the spindle (all labelled ``bearing``) still has surfaces in the
        # room air: its nodes are the places then
        nodes = nodes_of(network, ("structure", "housing", "table", "motor")) or nodes_of(network, ("bearing",))
        return [{"nodes": [n]} for n in nodes] or [{}]

    def _declare(self, before, after, p, o):
        edges = added(before, after, "edges")
        return [FreeParameter("G_W_K", tuple(f"edges.{e.name}.G_W_K" for e in edges), p["G_W_K"],
                          *log_bounds(self.parameters[0], p["G_W_K"]), "W/K", factor=1.0 / len(edges))]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", AmbientCoupling.id, AmbientCoupling)
