"""contact_resistance — a joint that conducts worse than the network assumes (series resistance R).

Replaces the conductance G of one joint (option ``edge``; default the first ``contact`` edge, else the first
node–node edge) by 1/(1/G + R), the speed-dependent part scaled alike.

Parameters: ``R_K_W`` = 0.1 [0, 5] K/W (neutral 0).
Direction: the gradient across the joint grows; the downstream node warms less and later.
Residual signature when missing: gradient across a joint too small; the downstream sensor lags. Test: a series
resistance on one edge fixes the downstream channels only.
"""

import dataclasses

from thermodrift.core.errors import InputError
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import FreeParameter, Mechanism, Parameter
from thermodrift.core.physics.network import BOUNDARIES


class ContactResistance(Mechanism):
    id = "contact_resistance"
    summary = "a joint that conducts worse than the network assumes (series resistance R)"
    experiment = "sensors on both sides of the joint"
    signed = True  # a negative fitted amplitude is still physical
    parameters = (Parameter("R_K_W", 0.1, 0.0, 5.0, "K/W", 0.0, "series thermal resistance of the joint"),)
    options = {"edge": None}
    signature = "gradient across a joint too small; downstream sensor lags"

    def _apply(self, network, p, o):
        inner = [e for e in network.edges if e.b not in BOUNDARIES]
        if o["edge"]:
            chosen = [e for e in network.edges if e.name == o["edge"]]
        else:
            chosen = [e for e in inner if e.kind == "contact"][:1] or inner[:1]
        if not chosen:
            edges = ", ".join(e.name for e in network.edges)
            raise InputError(f"mechanism {self.id!r}: network {network.name!r} has no edge "
                             f"{o['edge'] or 'between nodes'}", hint=f"edges: {edges}")
        e = chosen[0]
        factor = 1.0 / (1.0 + p["R_K_W"] * e.G_W_K)
        return network.replace(dataclasses.replace(e, G_W_K=e.G_W_K * factor, G_rot_W_K=e.G_rot_W_K * factor))

    @classmethod
    def places(cls, network):
        return [{"edge": e.name} for e in network.edges if e.b not in BOUNDARIES and e.G_W_K > 0][:8]

    def _declare(self, before, after, p, o):
        # R maps onto the joint's conductance G' = G/(1 + R·G), searched directly (R = 1/G' − 1/G).
        old = {e.name: e for e in before.edges}
        e = next(e for e in after.edges if e.name in old and old[e.name] != e)
        g0 = old[e.name].G_W_K
        return [FreeParameter("G_joint_W_K", (f"edges.{e.name}.G_W_K",), e.G_W_K, g0 / (1.0 + 5.0 * g0),
                          g0 / (1.0 + 1e-3 * g0), "W/K")]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", ContactResistance.id, ContactResistance)
