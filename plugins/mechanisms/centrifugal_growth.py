"""centrifugal_growth — the spindle nose grows under centrifugal force (and bearing contact change) at once.

Adds c·(n/n_ref)² µm to the outputs along ``axes`` (default ``z``, else the first output): an instantaneous
step at every speed change, with no thermal lag (0.3–1 µm in FL_THERMAL).

Parameters: ``um_at_ref`` = 1.0 [−20, 20] µm at the reference speed (neutral 0): 0.3–1 µm on FL_THERMAL, and
several µm up to about 15 µm on large high-speed (HSK) spindles near their top speed.
Direction: displacement jumps by c·(n₂² − n₁²)/n_ref² at each speed change.
Residual signature when missing: instantaneous step at speed changes ∝ n², no lag. Test: step heights vs n².
"""

import dataclasses

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import FreeParameter, Mechanism, Parameter, changed_outputs, target_outputs

LIMIT_UM = 20.0  # physical bound of the growth at the reference speed (µm), either sign


class CentrifugalGrowth(Mechanism):
    id = "centrifugal_growth"
    summary = "the spindle nose grows under centrifugal force (and bearing contact change) at once"
    experiment = "short speed steps (minutes) that leave no time to warm"
    signed = True  # a negative fitted amplitude is still physical
    at_once = True  # no thermal lag: complete within one sample of a speed change
    parameters = (Parameter("um_at_ref", 1.0, -LIMIT_UM, LIMIT_UM, "um", 0.0, "growth at the reference speed"),)
    options = {"axes": ("z",)}
    drivers = ("speed",)
    signature = "instantaneous step at speed changes ∝ n², no lag"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "speed_squared", "taus_s": (30.0, 120.0), "reaches": ("displacement",), "axes": ("z",)}
    laws = ("growth ∝ speed²",)

    def _apply(self, network, p, o):
        names = target_outputs(network, self.id, o["axes"])
        return network.replace(*[dataclasses.replace(out, centrifugal_um=out.centrifugal_um + p["um_at_ref"])
                                 for out in network.outputs if out.name in names])

    @classmethod
    def places(cls, network):
        # An axis whose outputs already carry a centrifugal term has it solved linearly: nothing to add there.
        axes = dict.fromkeys(o.axis for o in network.outputs)
        return [{"axes": [a]} for a in axes
                if not any(o.centrifugal_um for o in network.outputs if o.axis == a)]

    def _declare(self, before, after, p, o):
        outs = changed_outputs(before, after)
        return [FreeParameter("um_at_ref", (f"outputs.{n}.centrifugal_um",), p["um_at_ref"], -LIMIT_UM, LIMIT_UM, "um",
                          scale="projected", offset=before.output(n).centrifugal_um) for n in outs]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", CentrifugalGrowth.id, CentrifugalGrowth)
