"""The lumped-parameter thermal network: nodes, conductances, heat sources, outputs and sensors.

State equation (one row per node i, temperatures T in °C)::

    C_i dT_i/dt = Σ_j G_ij(n) (T_j − T_i) + G_i,amb(n) (T_amb − T_i) + advection + Q_i(n, T, signals)

* :class:`Node` — heat capacity C (J/K) and a ``group`` (bearing, shaft, motor, housing, structure, coolant,
  table, screw, tool) that mechanisms use to find where to act; ``reading``: a node of negligible capacity that
  only follows another (a lagged reading in an expansion map), no part for a mechanism to act on.
* :class:`Edge` — conductance G (W/K) between two nodes or a node and a boundary (``ambient`` or ``coolant``);
  convection on rotating parts grows as G + G_rot·(n/n_ref)^0.7. Radiation is linearised:
  G = 4εσT_m³A (:func:`radiation_conductance`).
* :class:`Advection` — coolant flow ṁc_p (W/K) carrying heat from ``upstream`` (a node or the ``coolant``
  inlet boundary) into ``downstream``; it is directional, so a chain of jacket nodes is an upwind scheme.
* Heat sources (W): :class:`BearingSource` (Palmgren: viscous ∝ n^(5/3), load ∝ n, viscous heat falling as the
  oil warms), :class:`MotorSource` (no-load losses ∝ n^p plus cutting power × (1/η − 1)), :class:`CuttingSource`
  (a fraction of the cutting power), :class:`AxisDriveSource` (∝ |v|^(1+k)) and :class:`PreloadFeedback`
  (heat ∝ n·(T_hot − T_cold), the thermally induced preload).
* :class:`Output` — a displacement channel (µm): Σ s_i (T_i − T_i,0) + Σ k (ΔT_hot − ΔT_cold) + c (n/n_ref)²,
  where T_i,0 is the initial state and the last term is the instantaneous centrifugal growth.

Everything temperature-dependent is linear in T at a fixed speed (the viscosity law is linearised about its
reference temperature), so a constant operating level is a linear time-invariant system that
:mod:`thermodrift.core.physics.integrate` steps exactly.

A :class:`Network` is immutable; :meth:`Network.parameters` lists every numeric parameter under a dotted path
(``edges.shaft-ambient.G_W_K``, ``outputs.z.sensitivity_um_K.shaft``) and :meth:`Network.with_values` returns
a copy with some of them changed — the hook for calibration.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

from thermodrift.core.errors import InputError
from thermodrift.core.physics.sensors import DisplacementSensor, Sensor, TemperatureSensor
from thermodrift.core.recording import TEMPERATURE_ROLES

BOUNDARIES = ("ambient", "coolant")
GROUPS = ("bearing", "shaft", "motor", "housing", "structure", "coolant", "table", "screw", "tool", "reading")
EDGE_KINDS = ("conduction", "contact", "convection", "radiation")
STEFAN_BOLTZMANN_W_M2K4 = 5.670374419e-8


def _p(unit: str, low: float | None = None, doc: str = "", high: float | None = None) -> dict:
    return {"unit": unit, "min": low, "max": high, "doc": doc}


def radiation_conductance(emissivity: float, area_m2: float, mean_degC: float = 25.0) -> float:
    """Linearised radiation to the surroundings, G = 4εσT_m³A (W/K); ≈ 5.4 W/m²K for ε = 0.9 at 25 °C."""
    return 4.0 * emissivity * STEFAN_BOLTZMANN_W_M2K4 * (mean_degC + 273.15) ** 3 * area_m2


@dataclass(frozen=True)
class Node:
    """A lumped mass at one temperature."""

    name: str
    capacity_J_K: float = field(metadata=_p("J/K", 0.0, "heat capacity m·c"))
    group: str = "structure"


@dataclass(frozen=True)
class Edge:
    """Heat path a–b with G(n) = G_W_K + G_rot_W_K·(n/n_ref)^rot_exponent (W/K); ``b`` may be a boundary."""

    name: str
    a: str
    b: str
    G_W_K: float = field(metadata=_p("W/K", 0.0, "conductance at standstill"))
    kind: str = "conduction"  # conduction | contact | convection | radiation (documentation and targeting)
    G_rot_W_K: float = field(default=0.0, metadata=_p("W/K", 0.0, "extra conductance at the reference speed"))
    rot_exponent: float = field(default=0.7, metadata=_p("1", 0.0, "speed exponent of the extra part"))

    def conductance(self, speed_ratio: float) -> float:
        """G (W/K) at speed n = speed_ratio · n_ref."""
        extra = self.G_rot_W_K * speed_ratio ** self.rot_exponent if self.G_rot_W_K and speed_ratio > 0 else 0.0
        return self.G_W_K + extra


@dataclass(frozen=True)
class Advection:
    """Coolant stream: heat flow flow·ṁc_p·(T_upstream − T_downstream) into ``downstream`` (W)."""

    name: str
    upstream: str
    downstream: str
    mdot_cp_W_K: float = field(metadata=_p("W/K", 0.0, "mass flow × specific heat at full flow"))


@dataclass(frozen=True)
class BearingSource:
    """Bearing friction heat into ``node``: Q = Q_v (n/n_ref)^e_v (1 − γ (T − T_γ)) + Q_l (n/n_ref)^e_l (W).

    Q_v is the viscous (Palmgren M0) heat at the reference speed and T_γ; γ is the linearised relative fall of
    viscous heat per K as the oil thins (0 switches it off). Linear in T keeps every speed level an LTI system;
    it is meant for γ·(T − T_γ) well below 1 (γ ≤ 0.05/K and a few tens of K).
    """

    name: str
    node: str
    viscous_W: float = field(metadata=_p("W", 0.0, "viscous heat at the reference speed"))
    load_W: float = field(default=0.0, metadata=_p("W", 0.0, "load-dependent heat at the reference speed"))
    viscous_exponent: float = field(default=5 / 3, metadata=_p("1", 0.0, "speed exponent of viscous heat"))
    load_exponent: float = field(default=1.0, metadata=_p("1", 0.0, "speed exponent of load heat"))
    viscosity_coeff_per_K: float = field(default=0.0, metadata=_p("1/K", 0.0, "relative viscous-heat fall per K", 0.05))
    viscosity_ref_degC: float = field(default=20.0, metadata=_p("degC", doc="temperature at which viscous_W holds"))

    def speed_terms(self, r: float) -> tuple[dict[str, float], list[tuple[str, str, float]]]:
        if r <= 0:
            return {}, []
        qv = self.viscous_W * r ** self.viscous_exponent
        q = qv * (1.0 + self.viscosity_coeff_per_K * self.viscosity_ref_degC) + self.load_W * r ** self.load_exponent
        linear = [(self.node, self.node, -self.viscosity_coeff_per_K * qv)] if self.viscosity_coeff_per_K else []
        return {self.node: q}, linear


@dataclass(frozen=True)
class MotorSource:
    """Motor losses split over nodes: no_load_W (n/n_ref)^exponent + cutting power·(1/η − 1) (W)."""

    name: str
    split: Mapping[str, float]  # node -> fraction, typically 2/3 stator, 1/3 rotor
    no_load_W: float = field(metadata=_p("W", 0.0, "iron and windage losses at the reference speed"))
    no_load_exponent: float = field(default=1.5, metadata=_p("1", 0.0, "speed exponent of no-load losses"))
    efficiency: float = field(default=0.9, metadata=_p("1", 0.5, "efficiency under cutting load", 1.0))

    def speed_terms(self, r: float) -> tuple[dict[str, float], list[tuple[str, str, float]]]:
        if r <= 0:
            return {}, []
        q = self.no_load_W * r ** self.no_load_exponent
        return {n: f * q for n, f in self.split.items()}, []

    def signal_power(self, signals: Mapping[str, Any]) -> Any:
        return signals["cutting_power_W"] * (1.0 / self.efficiency - 1.0)


@dataclass(frozen=True)
class CuttingSource:
    """Process heat: ``fraction`` of the cutting power (W) entering tool, workpiece and table nodes."""

    name: str
    split: Mapping[str, float]
    fraction: float = field(metadata=_p("1", 0.0, "share of the cutting power that heats the machine", 1.0))

    def signal_power(self, signals: Mapping[str, Any]) -> Any:
        return self.fraction * signals["cutting_power_W"]


@dataclass(frozen=True)
class AxisDriveSource:
    """Feed-drive heat (screw nut, bearings, motor): power_W · (|v|/v_ref)^exponent, split over nodes (W)."""

    name: str
    split: Mapping[str, float]
    power_W: float = field(metadata=_p("W", 0.0, "heat at the reference axis velocity"))
    exponent: float = field(default=1.3, metadata=_p("1", 0.0, "velocity exponent 1+k"))
    velocity_ref_mm_min: float = field(default=10_000.0, metadata=_p("mm/min", 1e-9, "reference axis velocity"))

    def signal_power(self, signals: Mapping[str, Any]) -> Any:
        return self.power_W * (abs(signals["axis_velocity_mm_min"]) / self.velocity_ref_mm_min) ** self.exponent


@dataclass(frozen=True)
class PreloadFeedback:
    """Heat into ``node`` that grows with the thermally induced preload: gain·(n/n_ref)·(T_hot − T_cold) (W)."""

    name: str
    node: str
    hot: str
    cold: str
    gain_W_K: float = field(metadata=_p("W/K", 0.0, "extra heat per K of shaft–housing difference at n_ref"))

    def speed_terms(self, r: float) -> tuple[dict[str, float], list[tuple[str, str, float]]]:
        if r <= 0 or not self.gain_W_K:
            return {}, []
        g = self.gain_W_K * r
        return {}, [(self.node, self.hot, g), (self.node, self.cold, -g)]


HeatSource = BearingSource | MotorSource | CuttingSource | AxisDriveSource | PreloadFeedback
SOURCE_TYPES: dict[str, type] = {"bearing": BearingSource, "motor": MotorSource, "cutting": CuttingSource,
                                 "axis_drive": AxisDriveSource, "preload_feedback": PreloadFeedback}


@dataclass(frozen=True)
class Output:
    """A displacement channel (µm) from node temperature rises, tilt terms and centrifugal growth."""

    name: str
    axis: str = "z"
    sensitivity_um_K: Mapping[str, float] = field(default_factory=dict)  # node -> µm/K (α·L)
    tilt_um_K: Mapping[str, float] = field(default_factory=dict)  # "hot/cold" -> µm per K of (ΔT_hot − ΔT_cold)
    centrifugal_um: float = field(default=0.0, metadata=_p("um", doc="instantaneous growth at the reference speed"))

    def tilt_pairs(self) -> list[tuple[str, str, float]]:
        return [(*key.split("/", 1), k) for key, k in self.tilt_um_K.items()]


_COLLECTIONS = ("nodes", "edges", "advections", "sources", "outputs", "sensors")


@dataclass(frozen=True)
class Network:
    """An immutable thermal network; see the module docstring. ``mechanisms`` records what was applied."""

    name: str
    nodes: tuple[Node, ...]
    edges: tuple[Edge, ...] = ()
    advections: tuple[Advection, ...] = ()
    sources: tuple[HeatSource, ...] = ()
    outputs: tuple[Output, ...] = ()
    sensors: tuple[Sensor, ...] = ()
    reference_speed_rpm: float = 5000.0
    description: str = ""
    mechanisms: tuple[dict, ...] = ()

    # --- lookup --------------------------------------------------------------------------------------------
    @property
    def node_names(self) -> list[str]:
        return [n.name for n in self.nodes]

    def node(self, name: str) -> Node:
        for n in self.nodes:
            if n.name == name:
                return n
        raise InputError(f"network {self.name!r} has no node {name!r}", hint=f"nodes: {', '.join(self.node_names)}")

    def nodes_in(self, *groups: str) -> list[str]:
        """Names of the nodes whose group is one of ``groups``, in network order."""
        return [n.name for n in self.nodes if n.group in groups]

    def output(self, name: str) -> Output:
        for o in self.outputs:
            if o.name == name:
                return o
        raise InputError(f"network {self.name!r} has no output {name!r}")

    @property
    def temperature_sensors(self) -> list[TemperatureSensor]:
        return [s for s in self.sensors if isinstance(s, TemperatureSensor)]

    @property
    def displacement_sensors(self) -> list[DisplacementSensor]:
        return [s for s in self.sensors if isinstance(s, DisplacementSensor)]

    # --- editing (always returns a new network) ------------------------------------------------------------
    def add(self, *elements: Any) -> "Network":
        """A copy with ``elements`` (nodes, edges, advections, sources, outputs, sensors) appended."""
        lists = {c: list(getattr(self, c)) for c in _COLLECTIONS}
        for e in elements:
            lists[_collection_of(e)].append(e)
        return dataclasses.replace(self, **{c: tuple(v) for c, v in lists.items()})

    def replace(self, *elements: Any) -> "Network":
        """A copy in which each element replaces the one of the same collection and name."""
        lists = {c: list(getattr(self, c)) for c in _COLLECTIONS}
        for e in elements:
            items = lists[_collection_of(e)]
            idx = [i for i, old in enumerate(items) if old.name == e.name]
            if not idx:
                raise InputError(f"network {self.name!r} has no {_collection_of(e)[:-1]} {e.name!r} to replace")
            items[idx[0]] = e
        return dataclasses.replace(self, **{c: tuple(v) for c, v in lists.items()})

    def parameters(self) -> dict[str, float]:
        """Every numeric parameter as ``{"<collection>.<element>.<field>[.<key>]": value}``."""
        out: dict[str, float] = {}
        for coll in _COLLECTIONS:
            for e in getattr(self, coll):
                for f in dataclasses.fields(e):
                    v = getattr(e, f.name)
                    if isinstance(v, (int, float)) and not isinstance(v, bool):
                        out[f"{coll}.{e.name}.{f.name}"] = float(v)
                    elif isinstance(v, Mapping):
                        out.update({f"{coll}.{e.name}.{f.name}.{k}": float(x) for k, x in v.items()})
        return out

    def with_values(self, values: Mapping[str, float]) -> "Network":
        """A copy with the parameters at the given dotted paths (see :meth:`parameters`) set.

        A mapping entry that does not exist yet (a new sensitivity ``outputs.z.sensitivity_um_K.column``) is
        added; an unknown element or field is an InputError.
        """
        net = self
        for path, value in values.items():
            parts = path.split(".", 3)
            if len(parts) < 3 or parts[0] not in _COLLECTIONS:
                raise InputError(f"bad parameter path {path!r}", hint="use <collection>.<element>.<field>[.<key>]")
            coll, name, fname = parts[:3]
            matches = [e for e in getattr(net, coll) if e.name == name]
            if not matches or fname not in {f.name for f in dataclasses.fields(matches[0])}:
                raise InputError(f"unknown parameter {path!r} in network {self.name!r}")
            elem = matches[0]
            if len(parts) == 4:
                new = dict(getattr(elem, fname))
                new[parts[3]] = float(value)
                elem = dataclasses.replace(elem, **{fname: new})
            else:
                elem = dataclasses.replace(elem, **{fname: float(value)})
            net = net.replace(elem)
        return net

    # --- checks --------------------------------------------------------------------------------------------
    def validate(self, file: str | None = None) -> "Network":
        """Check names, references, signs and that every node has a heat path to a boundary; returns self."""
        def fail(msg: str, hint: str | None = None) -> None:
            raise InputError(f"network {self.name!r}: {msg}", file=file, hint=hint)

        names = self.node_names
        if not names:
            fail("has no nodes")
        for coll in _COLLECTIONS:
            seen: set[str] = set()
            for e in getattr(self, coll):
                if e.name in seen:
                    fail(f"duplicate {coll[:-1]} name {e.name!r}")
                seen.add(e.name)
        for n in names:
            if n in BOUNDARIES:
                fail(f"node name {n!r} is reserved for a boundary")
        known = set(names) | set(BOUNDARIES)
        for n in self.nodes:
            if n.group not in GROUPS:
                fail(f"node {n.name!r} has unknown group {n.group!r}", f"use one of {', '.join(GROUPS)}")
            if not n.capacity_J_K > 0:
                fail(f"node {n.name!r} needs a positive capacity_J_K")

        def ref(where: str, name: str, allow_boundary: bool = True) -> None:
            if name not in (known if allow_boundary else set(names)):
                fail(f"{where} refers to unknown node {name!r}", f"nodes: {', '.join(names)}")

        for e in self.edges:
            if e.kind not in EDGE_KINDS:
                fail(f"edge {e.name!r} has unknown kind {e.kind!r}", f"use one of {', '.join(EDGE_KINDS)}")
            ref(f"edge {e.name!r}", e.a)
            ref(f"edge {e.name!r}", e.b)
            if e.a == e.b or e.a in BOUNDARIES:
                fail(f"edge {e.name!r} must join two different nodes, or a node (a) and a boundary (b)")
        for a in self.advections:
            ref(f"advection {a.name!r}", a.upstream)
            ref(f"advection {a.name!r}", a.downstream, allow_boundary=False)
        for s in self.sources:
            targets = [s.node] if hasattr(s, "node") else list(s.split)
            targets += [s.hot, s.cold] if isinstance(s, PreloadFeedback) else []
            for t in targets:
                ref(f"source {s.name!r}", t, allow_boundary=False)
            if hasattr(s, "split") and abs(sum(s.split.values()) - 1.0) > 1e-6:
                fail(f"source {s.name!r}: split fractions must sum to 1")
        for o in self.outputs:
            for t in list(o.sensitivity_um_K) + [x for pair in o.tilt_pairs() for x in pair[:2]]:
                ref(f"output {o.name!r}", t, allow_boundary=False)
        outputs = {o.name for o in self.outputs}
        for s in self.sensors:
            if isinstance(s, DisplacementSensor):
                if s.output not in outputs:
                    fail(f"sensor {s.name!r} reads unknown output {s.output!r}")
            else:
                if s.role not in TEMPERATURE_ROLES:
                    fail(f"sensor {s.name!r} has role {s.role!r}", f"use one of {', '.join(TEMPERATURE_ROLES)}")
                if abs(sum(s.weights.values()) - 1.0) > 1e-6:
                    fail(f"sensor {s.name!r}: node weights must sum to 1")
                for t in s.weights:
                    ref(f"sensor {s.name!r}", t)
        for coll in _COLLECTIONS:
            for e in getattr(self, coll):
                for fname, lo, hi, unit in _bounds(type(e)):
                    v = getattr(e, fname)
                    if lo is not None and v < lo or hi is not None and v > hi:
                        fail(f"{coll[:-1]} {e.name!r}: {fname} = {v} is outside [{lo}, {hi}] {unit}")
        self._check_grounded(fail)
        return self

    def _check_grounded(self, fail) -> None:
        """Every node must reach a boundary through conductances, or its temperature would drift forever."""
        links: dict[str, set[str]] = {n: set() for n in self.node_names}
        grounded: set[str] = set()
        for e in self.edges:
            if e.b in BOUNDARIES:
                grounded.add(e.a)
            else:
                links[e.a].add(e.b)
                links[e.b].add(e.a)
        for a in self.advections:
            if a.upstream in BOUNDARIES:
                grounded.add(a.downstream)
            else:  # a stream pulls its downstream node towards the upstream one, not the other way round
                links[a.upstream].add(a.downstream)
        stack, reached = list(grounded), set(grounded)
        while stack:
            for m in links[stack.pop()] - reached:
                reached.add(m)
                stack.append(m)
        floating = [n for n in self.node_names if n not in reached]
        if floating:
            fail(f"nodes {floating} have no heat path to ambient or coolant", "add a convection edge to 'ambient'")


@functools.cache
def _bounds(cls: type) -> list[tuple[str, float | None, float | None, str]]:
    """(field, min, max, unit) of every numeric field of an element class."""
    return [(f.name, f.metadata.get("min"), f.metadata.get("max"), f.metadata["unit"])
            for f in dataclasses.fields(cls) if "unit" in f.metadata]


def _collection_of(element: Any) -> str:
    for cls, coll in ((Node, "nodes"), (Edge, "edges"), (Advection, "advections"), (Output, "outputs"),
                      (TemperatureSensor, "sensors"), (DisplacementSensor, "sensors")):
        if isinstance(element, cls):
            return coll
    if isinstance(element, tuple(SOURCE_TYPES.values())):
        return "sources"
    raise TypeError(f"not a network element: {element!r}")


def iter_elements(network: Network) -> Iterable[tuple[str, Any]]:
    """(collection, element) for every element of ``network``."""
    for coll in _COLLECTIONS:
        for e in getattr(network, coll):
            yield coll, e
