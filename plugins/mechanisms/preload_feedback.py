"""preload_feedback — thermally induced bearing preload: a warmer shaft tightens the bearings, which heat more.

Adds at each bearing node a heat term gain·(n/n_ref)·(T_hot − T_cold), where hot is the shaft and cold the
housing (options ``hot``/``cold``, default the first shaft and first housing node). In a network with no housing
or structure node (an ``auto`` network whose every sensor rises with the spindle calls its housing sensors
bearings) the places take the bearing node itself as the cold side.

Parameters: ``gain_W_K`` = 1.0 [0, 10] W/K per bearing at the reference speed (neutral 0).
Direction: higher bearing temperatures and drift at high speed, growing super-linearly (self-reinforcing).
Residual signature when missing: super-linear growth at high speed, ∝ (T_shaft − T_housing)·n. Test:
likelihood-ratio test of the feedback term.
"""

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, log_bounds,
                                                 nodes_of, target_nodes, unique_name)
from thermodrift.core.physics.network import PreloadFeedback as FeedbackSource


class PreloadFeedback(Mechanism):
    id = "preload_feedback"
    summary = "thermally induced bearing preload: a warmer shaft tightens the bearings, which heat more"
    experiment = "a long run at top speed against one at half speed"
    parameters = (Parameter("gain_W_K", 1.0, 0.0, 10.0, "W/K", 0.0, "extra heat per K of shaft–housing difference"),)
    options = {"nodes": None, "hot": None, "cold": None}
    drivers = ("speed",)
    signature = "super-linear, self-reinforcing growth at high speed; ∝ (T_shaft − T_housing)·n"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "heat_feedback", "taus_s": (600.0, 1800.0, 7200.0), "sign": 1,
                       "drift_sense": True}
    laws = ("heat ∝ speed × (T_shaft − T_housing)",)

    def _apply(self, network, p, o):
        bearings = target_nodes(network, self.id, o["nodes"], ("bearing",))
        hot = target_nodes(network, self.id, o["hot"], ("shaft",))[0]
        cold = target_nodes(network, self.id, o["cold"], ("housing", "structure"))[0]
        names = [s.name for s in network.sources]
        added = []
        for b in bearings:
            names.append(unique_name(names, f"{b}_preload"))
            added.append(FeedbackSource(names[-1], b, hot, cold, p["gain_W_K"]))
        return network.add(*added)

    @classmethod
    def places(cls, network):
        if not network.nodes_in("shaft"):
            return []
        bearings = nodes_of(network, ("bearing",))
        if network.nodes_in("housing", "structure"):
            return [{"nodes": [n]} for n in bearings]
        return [{"nodes": [n], "cold": n} for n in bearings]

    def _declare(self, before, after, p, o):
        sources = added(before, after, "sources")
        return [FreeParameter("gain_W_K", tuple(f"sources.{s.name}.gain_W_K" for s in sources), p["gain_W_K"],
                          *log_bounds(self.parameters[0], p["gain_W_K"]), "W/K")]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", PreloadFeedback.id, PreloadFeedback)
