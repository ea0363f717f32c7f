"""Free parameters: which network values a calibration searches, where they sit, their bounds and scale."""

from __future__ import annotations

import dataclasses
import fnmatch
import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from thermodrift.core.errors import InputError
from thermodrift.core.physics.network import Network

# Fields that the default free set takes when positive (amplitudes and conductances, not exponents).
_DEFAULT_FREE_FIELDS = ("capacity_J_K", "G_W_K", "G_rot_W_K", "mdot_cp_W_K", "viscous_W", "load_W", "no_load_W",
                        "power_W", "fraction", "gain_W_K")


SCALES = ("log", "linear", "projected")


@dataclass(frozen=True)
class FreeParameter:
    """One free value of a network: its start ``value``, bounds ``low``/``high`` and ``unit``, and the network
    ``paths`` it sets (dotted, see :meth:`Network.parameters`); calibrations and mechanisms share this type.

    Path k takes the network value ``factor·value + offset`` (:meth:`network_value`), times ``scales[k]`` when
    ``scales`` is set (one factor shared by a group of parameters, each keeping its own start, :meth:`path_values`).
    A mechanism states its parameter in its own unit (a time constant in h that sets a capacity in J/K: ``factor``;
    a shift added to the network's exponent: ``offset``); a calibration's own parameters are network values.

    ``scale``: ``log`` searches the log of the network value (so steps and intervals are relative; the network
    value must stay positive), ``linear`` the network value itself (signed parameters), ``projected`` marks a
    value that enters the outputs linearly, which the search solves by least squares with the sensitivities
    instead of searching it. ``projected_by``: a temperature channel whose reading is linear in this heat
    amplitude; the search then solves it by linear least squares too (only the ``auto`` network sets it).
    """

    name: str
    paths: tuple[str, ...]
    value: float
    low: float
    high: float
    unit: str = ""
    scale: str = "log"
    factor: float = 1.0
    offset: float = 0.0
    projected_by: str | None = None
    scales: tuple[float, ...] = ()

    def __post_init__(self):
        if self.scale not in SCALES:
            raise InputError(f"free parameter {self.name!r} has scale {self.scale!r}",
                             hint=f"use one of {', '.join(SCALES)}")
        if not self.factor > 0:
            raise InputError(f"free parameter {self.name!r}: factor must be positive, got {self.factor:g}")
        if not self.low <= self.value <= self.high or (self.log and self.network_value(self.low) <= 0):
            need = "0 < low ≤ value ≤ high" if self.log else "low ≤ value ≤ high"
            if self.log and (self.factor, self.offset) != (1.0, 0.0):
                need = "low ≤ value ≤ high and a positive network value at low"
            raise InputError(f"free parameter {self.name!r}: need {need}, got "
                             f"{self.low:g} ≤ {self.value:g} ≤ {self.high:g}")

    @property
    def log(self) -> bool:
        """True when the search runs over the log of the network value."""
        return self.scale == "log"

    def network_value(self, value: float) -> float:
        """The network value (before ``scales``) that ``value`` sets."""
        return self.factor * value + self.offset

    def from_network(self, network_value: float) -> float:
        """The parameter value of a network value (inverse of :meth:`network_value`)."""
        return (network_value - self.offset) / self.factor

    def path_values(self, value: float) -> dict[str, float]:
        """Network value per path: :meth:`network_value` on every path, times ``scales[k]`` on path k when set."""
        v = self.network_value(value)
        if self.scales:
            return {path: v * k for path, k in zip(self.paths, self.scales)}
        return {path: v for path in self.paths}

    def to_search(self, v: float) -> float:
        """Search coordinate of a value: the log of its network value for log parameters, else the network value."""
        x = self.network_value(v)
        return math.log(x) if self.log else float(x)

    def from_search(self, theta: float) -> float:
        """Value of a search coordinate."""
        return self.from_network(math.exp(theta) if self.log else float(theta))

    def on_network_scale(self, start: float) -> FreeParameter:
        """This parameter stated in network values (factor 1, offset 0), starting at ``start`` (its own unit,
        clipped into the bounds): what a search over the network's own scale takes. Log bounds move inward by a
        relative 1e-9, since exp(log(x)) can land a rounding step past a limit."""
        lo, hi = sorted((self.network_value(self.low), self.network_value(self.high)))
        if self.log:
            lo, hi = lo * (1 + 1e-9), hi * (1 - 1e-9)
        return FreeParameter(self.name, self.paths, float(min(max(self.network_value(start), lo), hi)), lo, hi,
                             self.unit, scale=self.scale)


def _unit_of(path: str) -> str:
    for suffix, unit in (("_J_K", "J/K"), ("_W_K", "W/K"), ("_W", "W"), ("exponent", "1"), ("fraction", "1")):
        if path.endswith(suffix):
            return unit
    return ""


def free_from_paths(network: Network, patterns: Sequence[str], spread: float = 100.0) -> list[FreeParameter]:
    """Free parameters for every positive network parameter whose path matches one of ``patterns`` (globs),
    bounded to [value/spread, value·spread] (exponents: [0.3, 3])."""
    values = network.parameters()
    out = []
    for path, v in values.items():
        if any(fnmatch.fnmatchcase(path, p) for p in patterns):
            if v <= 0:
                raise InputError(f"free parameter {path!r} is {v:g}; only positive parameters can be calibrated "
                                 "in log space", hint="give it a positive start value in the network spec")
            low, high = (0.3, 3.0) if path.endswith("exponent") else (v / spread, v * spread)
            out.append(FreeParameter(path, (path,), v, min(low, v), max(high, v), _unit_of(path)))
    missing = [p for p in patterns if not any(fnmatch.fnmatchcase(path, p) for path in values)]
    if missing:
        raise InputError(f"free parameter pattern(s) {missing} match nothing in network {network.name!r}",
                         hint="paths look like edges.<edge>.G_W_K or nodes.<node>.capacity_J_K")
    return out


def default_free(network: Network) -> list[FreeParameter]:
    """Every positive capacity, conductance, advection and heat-source amplitude of ``network``."""
    paths = [p for p, v in network.parameters().items()
             if p.split(".")[0] in ("nodes", "edges", "advections", "sources")
             and p.split(".")[-1] in _DEFAULT_FREE_FIELDS and v > 0]
    return free_from_paths(network, paths)


def set_values(network: Network, values: Mapping[str, float]) -> Network:
    """``network.with_values(values)`` with one replacement per element (the search calls it per evaluation)."""
    changes: dict[tuple[str, str], dict[str, Any]] = {}
    for path, v in values.items():
        coll, name, fname, *key = path.split(".", 3)
        fields = changes.setdefault((coll, name), {})
        if key:
            fields[fname] = {**fields.get(fname, getattr(_element(network, coll, name, path), fname)), key[0]: v}
        else:
            fields[fname] = v
    colls = {}
    for (coll, name), fields in changes.items():
        items = colls.setdefault(coll, list(getattr(network, coll)))
        i = next((i for i, e in enumerate(items) if e.name == name), None)
        if i is None:
            raise InputError(f"unknown parameter path {coll}.{name}.* in network {network.name!r}")
        items[i] = dataclasses.replace(items[i], **fields)
    return dataclasses.replace(network, **{c: tuple(v) for c, v in colls.items()})


def _element(network: Network, coll: str, name: str, path: str) -> Any:
    for e in getattr(network, coll):
        if e.name == name:
            return e
    raise InputError(f"unknown parameter {path!r} in network {network.name!r}")
