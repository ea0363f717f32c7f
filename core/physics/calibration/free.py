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


@dataclass(frozen=True)
class FreeParameter:
    """One searched value, written to every network path in ``paths`` (dotted, see :meth:`Network.parameters`).

    ``value`` is the start, ``low``/``high`` the bounds (same unit). ``log=True`` searches log(value) (needs
    0 < low), so steps and intervals are relative; ``log=False`` searches the value itself (signed parameters).
    ``projected_by``: a temperature channel whose reading is linear in this heat amplitude; the search then
    solves it by linear least squares instead (only the ``auto`` network sets it). ``scales``: the value is a
    factor and path k takes ``value × scales[k]`` (grouped parameters, :meth:`path_values`).
    """

    name: str
    paths: tuple[str, ...]
    value: float
    low: float
    high: float
    unit: str = ""
    log: bool = True
    projected_by: str | None = None
    scales: tuple[float, ...] = ()

    def path_values(self, value: float) -> dict[str, float]:
        """Network value per path: ``value`` on every path, or ``value × scales[k]`` on path k when ``scales`` is
        set (one factor shared by a group of parameters, each keeping its own start value)."""
        if self.scales:
            return {path: value * k for path, k in zip(self.paths, self.scales)}
        return {path: value for path in self.paths}

    def __post_init__(self):
        if not self.low <= self.value <= self.high or (self.log and self.low <= 0):
            need = "0 < low ≤ value ≤ high" if self.log else "low ≤ value ≤ high"
            raise InputError(f"free parameter {self.name!r}: need {need}, got "
                             f"{self.low:g} ≤ {self.value:g} ≤ {self.high:g}")

    def to_search(self, v: float) -> float:
        """Search coordinate of a value (log for log parameters)."""
        return math.log(v) if self.log else float(v)

    def from_search(self, theta: float) -> float:
        """Value of a search coordinate."""
        return math.exp(theta) if self.log else float(theta)


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
