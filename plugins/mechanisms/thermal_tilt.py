"""thermal_tilt — bending of column or headstock from a temperature difference across it.

Adds k·(ΔT_hot − ΔT_cold) to the outputs along ``axes`` (default x, y; else the first output), where hot and cold
default to the first housing and the first structure node (options ``hot``, ``cold``). A 1 K front–back
gradient over a 1 m steel column bends it by ≈ 11.5 µm.

Parameters: ``um_K`` = 3.0 [−20, 20] µm/K (neutral 0).
Direction: the X/Y channels follow the hot–cold difference, not the mean temperature.
Residual signature when missing: X/Y channels follow a temperature difference, not a mean. Test: sparse search
over difference features.
"""

import dataclasses

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import Mechanism, Parameter, target_nodes, target_outputs


class ThermalTilt(Mechanism):
    id = "thermal_tilt"
    parameters = (Parameter("um_K", 3.0, -20.0, 20.0, "um/K", 0.0, "displacement per K of hot–cold difference"),)
    options = {"hot": None, "cold": None, "axes": ("x", "y")}
    signature = "X/Y channels follow a temperature difference, not a mean"

    def _apply(self, network, p, o):
        hot = target_nodes(network, self.id, o["hot"], ("housing", "motor", "bearing"))[0]
        cold = target_nodes(network, self.id, o["cold"], ("structure", "table"))[0]
        key = f"{hot}/{cold}"
        names = target_outputs(network, self.id, o["axes"])
        return network.replace(*[dataclasses.replace(
            out, tilt_um_K={**out.tilt_um_K, key: out.tilt_um_K.get(key, 0.0) + p["um_K"]})
            for out in network.outputs if out.name in names])


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", ThermalTilt.id, ThermalTilt)
