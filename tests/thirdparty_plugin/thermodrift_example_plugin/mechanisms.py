"""Mechanism ``fan_cooling``: a motor fan blowing room air over the motor at a constant rate.

Adds a convection edge from each target node (default: the motor nodes, else the housing) to ``ambient``,
sharing ``G_W_K`` equally.

Parameters: ``G_W_K`` = 4.0 [0, 40] W/K (neutral 0).
Direction: the motor runs cooler under load and follows the room air closely when the spindle stops.
Residual signature when missing: the motor-side channels run warmer than simulated in proportion to their rise
over ambient, at every speed; largest at high load.
"""

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, log_bounds, nodes_of,
                                                 target_nodes, unique_name)
from thermodrift.core.physics.network import Edge


class FanCooling(Mechanism):
    """Extra convection (W/K) from the motor to the room air, independent of the spindle speed."""

    id = "fan_cooling"
    summary = "a motor fan blowing room air over the motor at a constant rate"
    experiment = "the motor's cool-down with the fan running and with it stopped"
    parameters = (Parameter("G_W_K", 4.0, 0.0, 40.0, "W/K", 0.0, "fan conductance to ambient, shared by the nodes"),)
    options = {"nodes": None, "groups": ("motor", "housing")}
    drivers = ("ambient",)
    signature = "motor-side channels warmer than simulated in proportion to their rise over ambient, at every speed"

    def _apply(self, network, p, o):
        nodes = target_nodes(network, self.id, o["nodes"], o["groups"])
        names = [e.name for e in network.edges]
        edges = []
        for n in nodes:
            names.append(unique_name(names, f"{n}-ambient_fan"))
            edges.append(Edge(names[-1], n, "ambient", p["G_W_K"] / len(nodes), kind="convection"))
        return network.add(*edges)

    @classmethod
    def places(cls, network):
        return [{"nodes": [n]} for n in nodes_of(network, ("motor", "housing"))] or [{}]

    def _declare(self, before, after, p, o):
        edges = added(before, after, "edges")
        return [FreeParameter("G_W_K", tuple(f"edges.{e.name}.G_W_K" for e in edges), p["G_W_K"],
                              *log_bounds(self.parameters[0], p["G_W_K"]), "W/K", factor=1.0 / len(edges))]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", FanCooling.id, FanCooling)
