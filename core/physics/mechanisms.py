"""Mechanisms: physically shaped modifications of a network that the missing-physics finder switches on and off.

A mechanism adds edges, nodes, sources or output terms (or changes sensors) with 1–3 named numeric parameters,
each with a default, physical bounds, a unit and a *neutral* value at which the mechanism changes nothing.
Non-numeric ``options`` say where it acts (node groups, an edge, output axes); their defaults find the place
from node groups, so one mechanism fits every network.

Contract (what the finder and calibration rely on)::

    mech = registry.create("mechanism", "ambient_coupling")   # options as keyword arguments
    net2 = mech.apply(net, G_W_K=3.0)                         # a new Network; ``net`` is unchanged
    mech.apply(net, **mech.neutral())                         # simulates exactly like ``net``
    net2.mechanisms[-1]                                       # {"id", "params", "options"} record
    type(mech).parameters                                     # (Parameter(name, default, low, high, unit, ...),)

Writing one: subclass :class:`Mechanism`, set ``id``, ``parameters``, ``options`` and ``signature`` (the
residual signature a missing instance leaves), and implement ``_apply(network, p, o)`` where ``p`` holds the
parameter values and ``o`` the options. Register the class with ``thermodrift_register_mechanisms``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

from thermodrift.core.errors import InputError
from thermodrift.core.physics.network import Network
from thermodrift.core.physics.spec import plain


@dataclass(frozen=True)
class Parameter:
    """A numeric mechanism parameter: default, bounds [low, high], unit, and the value that switches it off."""

    name: str
    default: float
    low: float
    high: float
    unit: str
    neutral: float
    doc: str = ""


class Mechanism:
    """Base class; see the module docstring. The constructor stores options only (scikit-learn style)."""

    id: ClassVar[str] = ""
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    options: ClassVar[dict[str, Any]] = {}
    signature: ClassVar[str] = ""

    def __init__(self, **options: Any):
        unknown = set(options) - set(self.options)
        if unknown:
            raise InputError(f"mechanism {self.id!r}: unknown option(s) {sorted(unknown)}",
                             hint=f"options: {', '.join(self.options) or 'none'}")
        self.chosen = {**self.options, **options}

    def __repr__(self) -> str:
        changed = {k: v for k, v in self.chosen.items() if v != self.options[k]}
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in changed.items())})"

    @classmethod
    def defaults(cls) -> dict[str, float]:
        return {p.name: p.default for p in cls.parameters}

    @classmethod
    def neutral(cls) -> dict[str, float]:
        """Parameter values at which :meth:`apply` leaves the simulated outputs unchanged."""
        return {p.name: p.neutral for p in cls.parameters}

    @classmethod
    def bounds(cls) -> dict[str, tuple[float, float]]:
        return {p.name: (p.low, p.high) for p in cls.parameters}

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{}]

    @classmethod
    def describe(cls) -> str:
        """One line per parameter: name, default, bounds and unit."""
        rows = [f"{p.name} = {p.default:g} [{p.low:g}, {p.high:g}] {p.unit}: {p.doc}" for p in cls.parameters]
        return "\n".join([f"{cls.id}: {cls.signature}", *rows])

    def apply(self, network: Network, **params: float) -> Network:
        """A copy of ``network`` with this mechanism added at ``params`` (defaults for the ones not given)."""
        unknown = set(params) - {p.name for p in self.parameters}
        if unknown:
            raise InputError(f"mechanism {self.id!r}: unknown parameter(s) {sorted(unknown)}",
                             hint=f"parameters: {', '.join(p.name for p in self.parameters)}")
        values = {**self.defaults(), **{k: float(v) for k, v in params.items()}}
        for p in self.parameters:
            if not p.low <= values[p.name] <= p.high:
                raise InputError(f"mechanism {self.id!r}: {p.name} = {values[p.name]:g} {p.unit} is outside "
                                 f"[{p.low:g}, {p.high:g}]")
        out = self._apply(network, values, dict(self.chosen))
        record = {"id": self.id, "params": values, "options": plain(self.chosen)}
        return dataclasses.replace(out, mechanisms=(*network.mechanisms, record))

    def _apply(self, network: Network, p: dict[str, float], o: dict[str, Any]) -> Network:
        raise NotImplementedError


# --- helpers for mechanism plugins ------------------------------------------------------------------------------

def target_nodes(network: Network, mechanism: str, nodes: Sequence[str] | str | None,
                 groups: Sequence[str]) -> list[str]:
    """Explicit ``nodes`` (checked), else the network's nodes in the first of ``groups`` that has any."""
    if nodes:
        names = [nodes] if isinstance(nodes, str) else list(nodes)
        for n in names:
            network.node(n)
        return names
    for g in groups:
        found = network.nodes_in(g)
        if found:
            return found
    raise InputError(f"mechanism {mechanism!r}: network {network.name!r} has no node in groups {list(groups)}",
                     hint="name the nodes with the 'nodes' option")


def target_outputs(network: Network, mechanism: str, axes: Sequence[str] | str | None,
                   fallback_first: bool = True) -> list[str]:
    """Names of the outputs along ``axes`` (all outputs when ``axes`` is None)."""
    if axes is None:
        return [o.name for o in network.outputs]
    axes = [axes] if isinstance(axes, str) else list(axes)
    found = [o.name for o in network.outputs if o.axis in axes]
    if not found and fallback_first and network.outputs:
        found = [network.outputs[0].name]
    if not found:
        raise InputError(f"mechanism {mechanism!r}: network {network.name!r} has no output along {axes}")
    return found


def unique_name(existing: Sequence[str], base: str) -> str:
    """``base``, or ``base_2``, ``base_3`` … if taken."""
    name, i = base, 2
    while name in existing:
        name, i = f"{base}_{i}", i + 1
    return name
