"""axis_drive_heat — feed-drive heat (screw nut, support bearings, servo motor) ∝ |v|^(1+k).

Adds a feed-drive source ``power_W``·(|v|/10 m/min)^``exponent`` (scenario ``axis_velocity_mm_min``) into the
screw node; if the network has none, adds ``ball_screw`` (group screw, ``capacity_J_K`` option) joined to
ambient by ``ambient_W_K``. The screw's expansion enters the outputs along ``axes`` (default x, y; else the
first output) with ``sensitivity_um_K``. The heat is spread over the lumped screw (no travel position).

Parameters: ``power_W`` = 40 [0, 400] W (neutral 0), ``exponent`` = 1.3 [1, 2.5], ``sensitivity_um_K`` = 3.0
[−15, 15] µm/K (neutral 0).
Direction: the axis channels drift while the axis moves, also with the spindle idle.
Residual signature when missing: follows axis velocity, present with the spindle idle, position-dependent.
Test: regress on lagged Σ|v|.
"""

import dataclasses

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, changed_outputs,
                                                 log_bounds, target_outputs, unique_name)
from thermodrift.core.physics.network import AxisDriveSource, Edge, Node


class AxisDriveHeat(Mechanism):
    id = "axis_drive_heat"
    summary = "feed-drive heat (screw nut, support bearings, servo motor) ∝ |v|^(1+k)"
    experiment = "axis motion with the spindle stopped"
    parameters = (
        Parameter("power_W", 40.0, 0.0, 400.0, "W", 0.0, "drive heat at 10,000 mm/min"),
        Parameter("exponent", 1.3, 1.0, 2.5, "1", 1.3, "velocity exponent 1+k"),
        Parameter("sensitivity_um_K", 3.0, -15.0, 15.0, "um/K", 0.0, "axis error per K of the screw"),
    )
    options = {"axes": ("x", "y"), "capacity_J_K": 6000.0, "ambient_W_K": 2.0}
    drivers = ("axis_velocity",)
    signature = "follows axis velocity; present with the spindle idle; position-dependent"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "axis_velocity", "taus_s": (900.0, 3600.0, 14400.0), "sign": 1}
    laws = ("drive heat as a power of axis velocity",)

    def _apply(self, network, p, o):
        added = []
        screws = network.nodes_in("screw")
        if screws:
            screw = screws[0]
        else:
            screw = unique_name(network.node_names, "ball_screw")
            added += [Node(screw, float(o["capacity_J_K"]), "screw"),
                      Edge(unique_name([e.name for e in network.edges], f"{screw}-ambient"), screw, "ambient",
                           float(o["ambient_W_K"]), kind="convection")]
        source = AxisDriveSource(unique_name([s.name for s in network.sources], "axis_drive"), {screw: 1.0},
                                 p["power_W"], p["exponent"])
        net = network.add(*added, source)
        names = target_outputs(net, self.id, o["axes"])
        return net.replace(*[dataclasses.replace(
            out, sensitivity_um_K={**out.sensitivity_um_K,
                                   screw: out.sensitivity_um_K.get(screw, 0.0) + p["sensitivity_um_K"]})
            for out in net.outputs if out.name in names])

    @classmethod
    def places(cls, network):
        axes = list(dict.fromkeys(o.axis for o in network.outputs))
        return [{"axes": [a]} for a in axes] or [{}]

    def _declare(self, before, after, p, o):
        source = added(before, after, "sources")[0]
        screw = next(iter(source.split))
        free = [FreeParameter("power_W", (f"sources.{source.name}.power_W",), p["power_W"],
                          *log_bounds(self.parameters[0], p["power_W"]), "W")]
        free += [FreeParameter(f"sensitivity_um_K[{n}]", (f"outputs.{n}.sensitivity_um_K.{screw}",),
                           p["sensitivity_um_K"], -15.0, 15.0, "um/K", scale="projected",
                           offset=before.output(n).sensitivity_um_K.get(screw, 0.0))
                 for n in changed_outputs(before, after)]
        return free


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", AxisDriveHeat.id, AxisDriveHeat)
