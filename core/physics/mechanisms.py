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

What the missing-physics finder needs besides ``apply`` (checked by ``thermodrift.testing``)::

    type(mech).drivers                          # recording roles it needs, e.g. ("cutting_power",)
    type(mech).missing_drivers(recording)       # None, or why it cannot act here ("no cutting_power channel")
    type(mech).places(net)                      # option sets, one per place it can act (node, edge, channel)
    net2, free = mech.declare(net, **params)    # applied network + its FreeParameter list (paths, bounds, scale)

A mechanism's free parameters are :class:`~thermodrift.core.physics.calibration.FreeParameter` s, the type
calibration searches: a parameter in the mechanism's unit, the network paths it sets (network value =
factor·value + offset), its bounds and start, and its scale: ``log`` (positive network value, searched in log
space), ``linear`` or ``projected`` (enters the outputs linearly: calibration's linear step solves it with the
sensitivities, so it is not searched). :meth:`Mechanism.declare` checks every path exists and that the bounds stay
inside the network field's physical limits.

Writing one: subclass :class:`Mechanism`, set ``id``, ``parameters``, ``options``, ``drivers`` and
``signature`` (the residual signature a missing instance leaves, used as evidence text), ``laws`` (the
nonlinear constitutive laws it assumes, if any), ``summary``, ``experiment``, ``shapes`` and ``signed`` (what the
finder reports and screens; see the class), implement
``_apply(network, p, o)`` where ``p`` holds the parameter values and ``o`` the options, and
``_declare(before, after, p, o)`` returning the free parameters; override ``places`` when it can act in more
than its default place. Register the class with ``thermodrift_register_mechanisms``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

import numpy as np

from thermodrift.core.errors import InputError
from thermodrift.core.physics.calibration.free import FreeParameter
from thermodrift.core.physics.network import Network, iter_elements
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
    drivers: ClassVar[tuple[str, ...]] = ()  # recording roles the mechanism needs (speed, ambient, ...)
    # Constitutive laws it assumes that are nonlinear in a temperature or a driver (a power of speed, T⁴), beyond
    # the network's linear elements; of candidates the data cannot tell apart the finder names the one with fewest.
    laws: ClassVar[tuple[str, ...]] = ()
    # What the finder reports and screens, declared here (checked by thermodrift.testing): a one-line ``summary``
    # of the physics it adds (the report's words); the ``experiment`` that exposes it on its own, named when two
    # candidates fit equally well (empty: "an experiment driving it alone"); response ``shapes`` (parameter
    # values) screened besides the defaults where its shape depends on a parameter; ``signed``: its amplitude may
    # take either sign (a negative fitted amplitude is still physical).
    summary: ClassVar[str] = ""
    experiment: ClassVar[str] = ""
    shapes: ClassVar[tuple[dict[str, float], ...]] = ()
    signed: ClassVar[bool] = False
    # ``at_once``: it acts with no thermal lag (a step within a sample of its driver's change); a record sampled
    # slower than the spindle's fastest heating cannot tell it from that heating (``diagnose --stochastic``).
    at_once: ClassVar[bool] = False

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
    def experiment_text(cls) -> str:
        """The experiment that exposes it on its own, in the report's words."""
        return cls.experiment or "an experiment driving it alone"

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
        drivers = f" (drivers: {', '.join(cls.drivers)})" if cls.drivers else ""
        return "\n".join([f"{cls.id}: {cls.signature}{drivers}", *rows])

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

    # --- what the finder needs ---------------------------------------------------------------------------------
    @classmethod
    def missing_drivers(cls, recording) -> str | None:
        """Why the recording cannot drive this mechanism (a missing or constant driver channel), else None."""
        for role in cls.drivers:
            cols = recording.columns(role)
            if not cols:
                return f"the recording has no {role} channel"
            values = recording.data[cols].to_numpy(dtype=float)
            if not (np.ptp(values, axis=0) > 0).any():
                return f"the {role} channel {cols[0]!r} is constant"
        return None

    @classmethod
    def places(cls, network: Network) -> list[dict[str, Any]]:
        """Option sets, one per place in ``network`` where the mechanism can act (default: its default place)."""
        return [{}]

    @classmethod
    def unplaced(cls, network: Network) -> str | None:
        """The reason the diagnosis reports when :meth:`places` is empty in ``network``, if the mechanism can say
        more than that it has no place: "skipped: …" (the parts it acts on are missing) or "nested in the baseline:
        …" (acting there would only duplicate what the network already has); else None."""
        return None

    def declare(self, network: Network, **params: float) -> tuple[Network, list[FreeParameter]]:
        """:meth:`apply` plus the free parameters it introduced, checked against the network's field limits."""
        out = self.apply(network, **params)
        values = {**self.defaults(), **{k: float(v) for k, v in params.items()}}
        free = self._declare(network, out, values, dict(self.chosen))
        check_free(out, free, self.id)
        return out, free

    def _declare(self, before: Network, after: Network, p: dict[str, float], o: dict[str, Any]) -> list[FreeParameter]:
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


def field_limits(network: Network, path: str) -> tuple[float, float]:
    """Physical limits [min, max] of the network field at ``path`` (from the element's field metadata)."""
    coll, name, fname = path.split(".", 3)[:3]
    for c, e in iter_elements(network):
        if c == coll and e.name == name:
            for f in dataclasses.fields(e):
                if f.name == fname:
                    lo, hi = f.metadata.get("min"), f.metadata.get("max")
                    return (-math.inf if lo is None else lo), (math.inf if hi is None else hi)
    raise InputError(f"network {network.name!r} has no parameter {path!r}")


def check_free(network: Network, free: Sequence[FreeParameter], mechanism: str) -> None:
    """Every path exists and the network values the bounds give stay inside each field's physical limits;
    InputError naming the parameter otherwise (:class:`FreeParameter` itself checks start, bounds and scale)."""
    known = network.parameters()
    for fp in free:
        where = f"mechanism {mechanism!r}: free parameter {fp.name!r}"
        for path in fp.paths:
            if path not in known:
                raise InputError(f"{where}: network {network.name!r} has no parameter {path!r}")
            lo, hi = field_limits(network, path)
            ends = (fp.network_value(fp.low), fp.network_value(fp.high))
            if ends[0] < lo - 1e-12 or ends[1] > hi + 1e-12:
                raise InputError(f"{where}: bounds give {path} in [{ends[0]:g}, {ends[1]:g}], outside its "
                                 f"limits [{lo:g}, {hi:g}]")


def log_bounds(p: Parameter, start: float) -> tuple[float, float]:
    """Positive search bounds for a parameter whose neutral value is 0: [start/1000 or low, high]."""
    return max(p.low, start * 1e-3), p.high


def nodes_of(network: Network, groups: Sequence[str]) -> list[str]:
    """The network's nodes in any of ``groups`` (one candidate place each)."""
    return network.nodes_in(*groups)


def added(before: Network, after: Network, collection: str) -> list[Any]:
    """Elements of ``collection`` that ``after`` has and ``before`` had not (by name)."""
    old = {e.name for e in getattr(before, collection)}
    return [e for e in getattr(after, collection) if e.name not in old]


def changed_outputs(before: Network, after: Network) -> list[str]:
    """Names of the outputs whose definition differs between ``before`` and ``after``."""
    old = {o.name: o for o in before.outputs}
    return [o.name for o in after.outputs if old.get(o.name) != o]
