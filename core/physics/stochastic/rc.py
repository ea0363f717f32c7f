"""Stochastic RC networks: thermal capacities joined by resistances, driven by boundary temperatures and heat
inputs, with process noise per state and measurement noise per output — a :class:`~.fit.Model`.

Per state i (capacity C_i):  C_i dT_i = [Σ_j (T_j − T_i)/R_ij + Σ_b (T_b − T_i)/R_ib + Σ_q g_iq q] dt + C_i σ_i dW_i
(written as dT_i = … /C_i dt + σ_i dW_i, σ_i in K/√(time unit)), where j runs over states, b over boundary
temperature inputs (outdoor air) and q over heat inputs (solar irradiance with an aperture g, the heating with
gain 1 or a named gain). Outputs read one state each plus measurement noise r (K). Resistances, capacities and
gains are named parameters (:class:`~.fit.Param`), so mechanisms add states and couplings by name.

Units follow the heat input: with heating in kW and time in h, C is in kWh/K and R in K/kW; with a unitless
heating signal, C and R are in that signal's units. ``time_unit_s`` is the time unit in seconds (3600 for
buildings).

A spec in YAML (``conf/network/building_ti.yaml``)::

    name: building_ti
    kind: stochastic_rc
    time_unit_s: 3600
    inputs: {Ta: {role: ambient, kind: temperature}, Ps: {role: solar_irradiance, kind: heat},
             Phi: {role: heating, kind: heat}}
    mechanisms: [{id: building_ti}]

or states, ``couplings`` (a, b, R), ``heat`` (state, input, gain), ``noise`` (state: σ parameter), ``outputs``
(name: {state, noise}) and ``parameters`` (name: {value, low, high, unit}) written out.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from thermodrift.core.errors import InputError
from thermodrift.core.physics.stochastic.fit import Param
from thermodrift.core.physics.stochastic.sde import System

_TOP = ("name", "description", "kind", "time_unit_s", "inputs", "states", "couplings", "heat", "noise", "outputs",
        "parameters", "mechanisms", "mechanisms_applied")


@dataclass(frozen=True)
class RCNetwork:
    """An immutable stochastic RC network (see the module docstring). ``inputs``: (name, role, kind) with kind
    ``temperature`` (a boundary) or ``heat``; ``states``: (name, capacity parameter); ``couplings``: (a, b,
    resistance parameter), b a state or a temperature input; ``heat``: (state, input, gain parameter or "" for
    gain 1); ``noise``: (state, σ parameter); ``outputs``: (name, state, r parameter); ``params``: the
    parameters; ``mechanisms``: records of the mechanisms applied."""

    name: str
    inputs: tuple[tuple[str, str, str], ...] = ()
    states: tuple[tuple[str, str], ...] = ()
    couplings: tuple[tuple[str, str, str], ...] = ()
    heat: tuple[tuple[str, str, str], ...] = ()
    noise: tuple[tuple[str, str], ...] = ()
    outputs: tuple[tuple[str, str, str], ...] = ()
    params: tuple[Param, ...] = ()
    time_unit_s: float = 3600.0
    description: str = ""
    mechanisms: tuple[dict, ...] = ()

    # --- the Model protocol -------------------------------------------------------------------------------------
    @property
    def parameters(self) -> tuple[Param, ...]:
        return self.params

    @property
    def state_names(self) -> list[str]:
        return [s for s, _ in self.states]

    @property
    def input_names(self) -> list[str]:
        return [i for i, _, _ in self.inputs]

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(name)

    def values(self) -> dict[str, float]:
        return {p.name: p.value for p in self.params}

    def system(self, values: Mapping[str, float] | None = None) -> System:
        v = self.values() if values is None else values
        S, I = self.state_names, self.input_names
        si, ii = {s: k for k, s in enumerate(S)}, {u: k for k, u in enumerate(I)}
        n, m = len(S), len(I)
        cap = np.array([v[c] for _, c in self.states])
        A, B = np.zeros((n, n)), np.zeros((n, m))
        for a, b, r in self.couplings:
            g = 1.0 / v[r]
            i = si[a]
            A[i, i] -= g
            if b in si:
                j = si[b]
                A[i, j] += g
                A[j, j] -= g
                A[j, i] += g
            else:
                B[i, ii[b]] += g
        for s, q, gain in self.heat:
            B[si[s], ii[q]] += v[gain] if gain else 1.0
        A, B = A / cap[:, None], B / cap[:, None]
        sigma = np.zeros(n)
        for s, p in self.noise:
            sigma[si[s]] = v[p]
        C = np.zeros((len(self.outputs), n))
        for k, (_, s, _) in enumerate(self.outputs):
            C[k, si[s]] = 1.0
        r = np.array([v[p] for _, _, p in self.outputs])
        return System(A[None], B[None], C, np.zeros((len(self.outputs), m)), sigma, r)

    # --- editing (what mechanisms use) ------------------------------------------------------------------------
    def with_params(self, *params: Param) -> "RCNetwork":
        """Parameters added, or replaced by name."""
        new = {p.name: p for p in params}
        kept = tuple(new.pop(p.name) if p.name in new else p for p in self.params)
        return dataclasses.replace(self, params=kept + tuple(new.values()))

    def with_values(self, values: Mapping[str, float]) -> "RCNetwork":
        """Parameter start values changed (clipped to their bounds); unknown names are ignored."""
        return dataclasses.replace(self, params=tuple(p.with_value(values[p.name]) if p.name in values else p
                                                       for p in self.params))

    def used(self) -> "RCNetwork":
        """The network without parameters that nothing refers to."""
        refs = ({c for _, c in self.states} | {r for *_, r in self.couplings} | {g for *_, g in self.heat if g}
                | {p for _, p in self.noise} | {p for *_, p in self.outputs})
        return dataclasses.replace(self, params=tuple(p for p in self.params if p.name in refs))

    def has_input(self, role: str) -> bool:
        return any(r == role for _, r, _ in self.inputs)

    def input_of(self, role: str) -> str:
        for name, r, _ in self.inputs:
            if r == role:
                return name
        raise InputError(f"network {self.name!r} has no input of role {role!r}")


def network_from_dict(spec: Mapping[str, Any], *, file: str | None = None, registry=None) -> RCNetwork:
    """Build an :class:`RCNetwork` from a spec mapping (module docstring), applying its ``mechanisms`` in order
    through the mechanism registry (``registry`` or the default one)."""
    if not isinstance(spec, Mapping):
        raise InputError("a network spec must be a mapping", file=file)
    unknown = set(spec) - set(_TOP)
    if unknown:
        raise InputError(f"unknown stochastic network spec key(s) {sorted(unknown)}", file=file,
                         hint=f"allowed: {', '.join(_TOP)}")
    try:
        inputs = tuple((str(k), str(v["role"]), str(v.get("kind", "heat"))) for k, v in (spec.get("inputs") or {}
                                                                                          ).items())
        params = tuple(Param(str(k), float(v["value"]), float(v.get("low", 0.0)), float(v.get("high", math.inf)),
                             str(v.get("unit", "")), str(v.get("doc", "")))
                       for k, v in (spec.get("parameters") or {}).items())
        net = RCNetwork(
            name=str(spec.get("name", "rc")), inputs=inputs,
            states=tuple((str(k), str(v)) for k, v in (spec.get("states") or {}).items()),
            couplings=tuple(tuple(map(str, c)) for c in spec.get("couplings") or ()),
            heat=tuple((str(h[0]), str(h[1]), str(h[2]) if len(h) > 2 and h[2] else "") for h in spec.get("heat")
                       or ()),
            noise=tuple((str(k), str(v)) for k, v in (spec.get("noise") or {}).items()),
            outputs=tuple((str(k), str(v["state"]), str(v["noise"])) for k, v in (spec.get("outputs") or {}
                                                                                   ).items()),
            params=params, time_unit_s=float(spec.get("time_unit_s", 3600.0)),
            description=str(spec.get("description", "")))
    except (KeyError, TypeError, ValueError, IndexError) as err:
        raise InputError(f"stochastic network spec: malformed entry ({err})", file=file) from None
    if registry is None:
        from thermodrift.core import registry as registry_module

        registry = registry_module.default()
    for m in spec.get("mechanisms") or ():
        if not isinstance(m, Mapping) or "id" not in m:
            raise InputError("each mechanism entry needs an 'id'", file=file)
        net = registry.create("mechanism", str(m["id"]), **(m.get("options") or {})).apply(
            net, **(m.get("params") or {}))
    check(net, file)
    return net


def check(net: RCNetwork, file: str | None = None) -> None:
    """Every reference names a state, input or parameter that exists; InputError otherwise."""
    S, I = set(net.state_names), set(net.input_names)
    P = {p.name for p in net.params}
    temps = {i for i, _, k in net.inputs if k == "temperature"}

    def need(ok: bool, what: str) -> None:
        if not ok:
            raise InputError(f"network {net.name!r}: {what}", file=file)
    for s, c in net.states:
        need(c in P, f"state {s!r}: unknown capacity parameter {c!r}")
    for a, b, r in net.couplings:
        need(a in S and (b in S or b in temps), f"coupling {a}–{b}: unknown state or temperature input")
        need(r in P, f"coupling {a}–{b}: unknown resistance parameter {r!r}")
    for s, q, g in net.heat:
        need(s in S and q in I, f"heat input {q!r} into {s!r}: unknown state or input")
        need(not g or g in P, f"heat input {q!r} into {s!r}: unknown gain parameter {g!r}")
    for s, p in net.noise:
        need(s in S and p in P, f"process noise of {s!r}: unknown state or parameter {p!r}")
    for o, s, p in net.outputs:
        need(s in S and p in P, f"output {o!r}: unknown state {s!r} or noise parameter {p!r}")


def load(source: str) -> RCNetwork:
    """A stochastic network from a YAML path or a name in ``conf/network`` (a spec with ``kind: stochastic_rc``)."""
    import importlib.resources
    from pathlib import Path

    import yaml

    path = Path(source)
    if not (path.suffix in (".yaml", ".yml") and path.exists()):
        path = Path(str(importlib.resources.files("thermodrift.conf.network") / f"{source}.yaml"))
        if not path.exists():
            raise InputError(f"unknown network {source!r}", hint="a YAML path or a name in conf/network")
    try:
        spec = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as err:
        raise InputError(f"not valid YAML ({str(err).splitlines()[0]})", file=str(path)) from None
    if not isinstance(spec, Mapping) or spec.get("kind") != "stochastic_rc":
        raise InputError("not a stochastic RC network spec (needs 'kind: stochastic_rc')", file=str(path))
    return network_from_dict(spec, file=str(path))


def is_stochastic_spec(source: str) -> bool:
    """Whether ``source`` (a path or a name in conf/network) is a stochastic RC spec."""
    try:
        load(source)
    except InputError:
        return False
    return True
