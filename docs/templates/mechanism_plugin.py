"""Template: a thermodrift mechanism plugin (a piece of physics the missing-physics finder can test) in one file.

How to use:
1. Copy this file into your package, e.g. ``my_physics/coolant_jacket.py``, and rename class and ``id``.
2. Fill in the ``todo`` parts. Keep the rules: ``__init__`` is the base class's (it stores ``options`` only);
   every parameter has a default, physical bounds, a unit and a *neutral* value at which ``apply`` changes no
   simulated reading; ``_apply`` returns a new network (``network.add(...)``), never changes the one given;
   ``_declare`` returns the free parameters, each naming the network paths it sets (they must exist in the
   applied network and hold the start value); ``places`` lists the option sets where it can act.
3. One entry-point line in your ``pyproject.toml``::

       [project.entry-points.thermodrift]
       coolant_jacket = "my_physics.coolant_jacket"

4. ``thermodrift diagnose TABLE --manifest M.yaml --mechanisms coolant_jacket ...`` screens it beside the
   built-in ones (without ``--mechanisms``, every registered mechanism is screened).
5. Check it: ``from thermodrift.testing import check_component; check_component("mechanism", "coolant_jacket")``
   or subclass ``thermodrift.testing.pytest_components.MechanismTests`` with ``name = "coolant_jacket"``.

The example adds a water jacket on the motor: a convection edge (W/K) from the motor nodes to ``ambient``.
"""

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import (FreeParameter, Mechanism, Parameter, added, log_bounds, nodes_of,
                                                 target_nodes, unique_name)
from thermodrift.core.physics.network import Edge


# todo: rename the class and say what physics it adds
class CoolantJacket(Mechanism):
    """A cooling jacket on the motor: extra conductance (W/K) from the motor nodes to the surroundings."""

    id = "coolant_jacket"  # todo: the registry name
    summary = "a cooling jacket on the motor"  # todo: one line in the report's words
    experiment = "the motor's cool-down with the jacket flowing and drained"  # todo: what exposes it alone
    # todo: Parameter(name, default, low, high, unit, neutral, doc): 1–3 numeric parameters
    parameters = (Parameter("G_W_K", 5.0, 0.0, 60.0, "W/K", 0.0, "jacket conductance, shared by the nodes"),)
    # todo: where it acts; the defaults find the place from node groups so one mechanism fits every network
    options = {"nodes": None, "groups": ("motor",)}
    drivers = ("ambient",)  # todo: the recording roles it needs (speed, cutting_power, coolant_inlet, ...)
    # todo: the residual a missing instance leaves, in one sentence (used as evidence text)
    signature = "motor channels warmer than simulated in proportion to their rise over the surroundings"

    def _apply(self, network, p, o):
        nodes = target_nodes(network, self.id, o["nodes"], o["groups"])
        names = [e.name for e in network.edges]
        edges = []
        for n in nodes:
            names.append(unique_name(names, f"{n}-ambient_jacket"))
            edges.append(Edge(names[-1], n, "ambient", p["G_W_K"] / len(nodes), kind="convection"))
        return network.add(*edges)

    # todo: one option set per place the finder should try (node, edge, channel)
    @classmethod
    def places(cls, network):
        return [{"nodes": [n]} for n in nodes_of(network, ("motor",))]

    # todo: the free parameters calibration searches, with the network paths they set
    def _declare(self, before, after, p, o):
        edges = added(before, after, "edges")
        return [FreeParameter("G_W_K", tuple(f"edges.{e.name}.G_W_K" for e in edges), p["G_W_K"],
                              *log_bounds(self.parameters[0], p["G_W_K"]), "W/K", factor=1.0 / len(edges))]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", CoolantJacket.id, CoolantJacket)
