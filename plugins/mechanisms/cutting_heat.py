"""cutting_heat — process heat from cutting entering tool, workpiece and table.

Adds a cutting source: ``fraction`` of the cutting power (scenario ``cutting_power_W``) split equally over the
target nodes (default: tool, else table, else the front bearings).

Parameters: ``fraction`` = 0.10 [0, 0.3] (neutral 0).
Direction: target temperatures and the displacement rise only while cutting, in proportion to the power.
Residual signature when missing: only in cutting windows; scales with cutting power, not speed. Test: split by
the cutting flag; regress on power.
"""

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, log_bounds,
                                                 nodes_of, target_nodes, unique_name)
from thermodrift.core.physics.network import CuttingSource


class CuttingHeat(Mechanism):
    id = "cutting_heat"
    summary = "process heat from cutting entering tool, workpiece and table"
    experiment = "cutting vs air-cutting at the same speed"
    parameters = (Parameter("fraction", 0.10, 0.0, 0.3, "1", 0.0, "share of the cutting power heating the machine"),)
    options = {"nodes": None, "groups": ("tool", "table", "bearing")}
    drivers = ("cutting_power",)
    signature = "only in cutting windows; scales with cutting power, not speed"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "cutting_power", "taus_s": (600.0, 1800.0, 7200.0), "sign": 1}

    def _apply(self, network, p, o):
        nodes = target_nodes(network, self.id, o["nodes"], o["groups"])
        name = unique_name([s.name for s in network.sources], "cutting_heat")
        return network.add(CuttingSource(name, {n: 1.0 / len(nodes) for n in nodes}, p["fraction"]))

    @classmethod
    def places(cls, network):
        groups = ("tool", "table", "bearing", "shaft", "housing", "structure")
        return [{"nodes": [n]} for n in nodes_of(network, groups)] or [{}]

    def _declare(self, before, after, p, o):
        source = added(before, after, "sources")[0]
        return [FreeParameter("fraction", (f"sources.{source.name}.fraction",), p["fraction"],
                          *log_bounds(self.parameters[0], p["fraction"]), "1")]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", CuttingHeat.id, CuttingHeat)
