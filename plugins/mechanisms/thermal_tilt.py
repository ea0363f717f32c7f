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
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, changed_outputs, nodes_of,
                                                 target_nodes, target_outputs)

HOT_GROUPS = ("housing", "motor", "bearing")  # the warm side of a tilt
COLD_GROUPS = ("structure", "table")          # the side it bends against


class ThermalTilt(Mechanism):
    id = "thermal_tilt"
    summary = "bending of column or headstock from a temperature difference across it"
    experiment = "sensors on opposite faces of the column"
    signed = True  # a negative fitted amplitude is still physical
    parameters = (Parameter("um_K", 3.0, -20.0, 20.0, "um/K", 0.0, "displacement per K of hot–cold difference"),)
    options = {"hot": None, "cold": None, "axes": ("x", "y")}
    signature = "X/Y channels follow a temperature difference, not a mean"
    # against a simulation: the spindle's heat bending the structure, on an X/Y drift the simulation does not move
    # with that heat (lags of r^1.5; either sign)
    simulation_form = {"driver": "bending", "taus_s": (1800.0, 7200.0, 28800.0), "reaches": ("displacement",),
                       "axes": ("x", "y")}

    def _apply(self, network, p, o):
        hot = target_nodes(network, self.id, o["hot"], HOT_GROUPS)[0]
        cold = target_nodes(network, self.id, o["cold"], COLD_GROUPS)[0]
        key = f"{hot}/{cold}"
        names = target_outputs(network, self.id, o["axes"])
        return network.replace(*[dataclasses.replace(
            out, tilt_um_K={**out.tilt_um_K, key: out.tilt_um_K.get(key, 0.0) + p["um_K"]})
            for out in network.outputs if out.name in names])

    @classmethod
    def places(cls, network):
        # A pair whose nodes both expand into the axis already is no new physics: the difference is a
        # combination of the sensitivities the network has.
        hot, cold = nodes_of(network, HOT_GROUPS), nodes_of(network, COLD_GROUPS)
        out = []
        for a in dict.fromkeys(o.axis for o in network.outputs):
            known = {n for o in network.outputs if o.axis == a for n in o.sensitivity_um_K}
            out += [{"hot": h, "cold": c, "axes": [a]} for h in hot[:3] for c in cold[:3]
                    if not (h in known and c in known)]
        return out[:12]

    @classmethod
    def unplaced(cls, network):
        if cls.places(network):
            return None
        hot, cold = nodes_of(network, HOT_GROUPS)[:3], nodes_of(network, COLD_GROUPS)[:3]
        if not cold or not hot:
            part = "structure or table" if not cold else "housing, motor or bearing"
            return f"skipped: the network has no {part} node to take the hot–cold difference of a tilt"
        return (f"nested in the baseline: every pair of its hot ({', '.join(hot)}) and cold ({', '.join(cold)}) "
                "nodes already expands into each axis, so a tilt is a combination of sensitivities the baseline "
                "fits; testing it needs an expansion map that leaves one node of the pair out (--network spec.yaml)")

    def _declare(self, before, after, p, o):
        out = []
        for n in changed_outputs(before, after):
            old, new = before.output(n).tilt_um_K, after.output(n).tilt_um_K
            key = next(k for k in new if new[k] != old.get(k))
            out.append(FreeParameter(f"um_K[{n}]", (f"outputs.{n}.tilt_um_K.{key}",), p["um_K"], -20.0, 20.0, "um/K",
                                 scale="projected", offset=old.get(key, 0.0)))
        return out


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", ThermalTilt.id, ThermalTilt)
