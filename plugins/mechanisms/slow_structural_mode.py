"""slow_structural_mode — a massive, slowly warming part whose expansion acts against the fast path.

Adds a node ``slow_structure`` (group structure) joined to the target node (default: the first structure,
else housing node; places: the structure, housing and table nodes, else the bearing nodes of a network that has
none) by ``G_W_K`` and to ambient by ``ambient_W_K`` (option), with capacity
τ·(G_W_K + ambient_W_K), and a sensitivity ``gain_um_K`` on the outputs along ``axes`` (default ``z``).

Parameters: ``tau_h`` = 4 [0.5, 24] h, ``gain_um_K`` = −2.0 [−10, 10] µm/K (neutral 0), ``G_W_K`` = 4 [0, 50] W/K
(neutral 0).
Direction: with a gain opposite to the fast path the step response is non-monotonic: the drift peaks and falls
back during a long run and overshoots past the start on cool-down (FL_THERMAL ch3/ch4).
Residual signature when missing: difference of two exponentials (τ2 ≫ τ1, opposite gain), overshoot on
cool-down. Test: an extra node with τ2 ≫ τ1 and opposite gain.
"""

import dataclasses

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, changed_outputs, nodes_of,
                                                 target_nodes, target_outputs, unique_name)
from thermodrift.core.physics.network import Edge, Node


class SlowStructuralMode(Mechanism):
    id = "slow_structural_mode"
    summary = "a massive, slowly warming part whose expansion acts against the fast path"
    experiment = "a cool-down of at least 12 h after a long run"
    shapes = ({"tau_h": 2.0}, {"tau_h": 6.0}, {"tau_h": 16.0})
    signed = True  # a negative fitted amplitude is still physical
    parameters = (
        Parameter("tau_h", 4.0, 0.5, 24.0, "h", 4.0, "time constant of the slow part"),
        Parameter("gain_um_K", -2.0, -10.0, 10.0, "um/K", 0.0, "output sensitivity to the slow part"),
        Parameter("G_W_K", 4.0, 0.0, 50.0, "W/K", 0.0, "conductance from the target node into the slow part"),
    )
    options = {"nodes": None, "groups": ("structure", "housing"), "axes": ("z",), "ambient_W_K": 2.0}
    signature = "non-monotonic step response: difference of two exponentials, overshoot on cool-down"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "slow_heat", "taus_s": (14400.0, 28800.0, 57600.0), "reaches": ("displacement",),
                       "axes": ("z",)}  # as its default option: the slow part acts along z

    def _apply(self, network, p, o):
        target = target_nodes(network, self.id, o["nodes"], o["groups"])[0]
        slow = unique_name(network.node_names, "slow_structure")
        g_amb = float(o["ambient_W_K"])
        names = [e.name for e in network.edges]
        into = Edge(unique_name(names, f"{target}-{slow}"), target, slow, p["G_W_K"], kind="contact")
        out = Edge(unique_name(names, f"{slow}-ambient"), slow, "ambient", g_amb, kind="convection")
        capacity = p["tau_h"] * 3600.0 * (p["G_W_K"] + g_amb)
        outputs = [dataclasses.replace(o_, sensitivity_um_K={**o_.sensitivity_um_K, slow: p["gain_um_K"]})
                   for o_ in network.outputs if o_.name in target_outputs(network, self.id, o["axes"])]
        return network.add(Node(slow, capacity, "structure"), into, out).replace(*outputs)

    @classmethod
    def places(cls, network):
        axes = list(dict.fromkeys(o.axis for o in network.outputs))
        # a network whose every node rises with the spindle (all labelled ``bearing``) still has a slow mass
        # behind its sensors: its nodes are the places then
        nodes = nodes_of(network, ("structure", "housing", "table")) or nodes_of(network, ("bearing",))
        return [{"nodes": [n], "axes": [a]} for n in nodes for a in axes][:8] or [{}]

    def _declare(self, before, after, p, o):
        # G_W_K stays at its value: τ and the gain describe the mode; the conductance only splits τ.
        slow = added(before, after, "nodes")[0]
        per_hour = 3600.0 * (p["G_W_K"] + float(o["ambient_W_K"]))
        free = [FreeParameter("tau_h", (f"nodes.{slow.name}.capacity_J_K",), p["tau_h"], 0.5, 24.0, "h",
                          factor=per_hour)]
        free += [FreeParameter(f"gain_um_K[{n}]", (f"outputs.{n}.sensitivity_um_K.{slow.name}",), p["gain_um_K"],
                           -10.0, 10.0, "um/K", scale="projected") for n in changed_outputs(before, after)]
        return free


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", SlowStructuralMode.id, SlowStructuralMode)
