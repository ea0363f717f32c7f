"""Network specs in YAML: schema, validation with clear InputErrors, and the named reference networks.

A spec (units are in the field names; ``thermodrift.core.physics.spec.schema()`` lists every field)::

    name: demo_spindle
    reference_speed_rpm: 6000            # n_ref for every speed law, rpm
    nodes:                               # name: {capacity_J_K, group}
      shaft: {capacity_J_K: 3700, group: shaft}
    edges:                               # a–b conductance; b may be the boundary 'ambient' or 'coolant'
      - {a: shaft, b: ambient, G_W_K: 0.8, kind: convection, G_rot_W_K: 2.5, rot_exponent: 0.7}
    advections:                          # coolant stream into 'downstream'
      - {upstream: coolant, downstream: jacket, mdot_cp_W_K: 280}
    sources:                             # name: {type: bearing|motor|cutting|axis_drive|preload_feedback, ...}
      front_bearing: {type: bearing, node: front_bearing, viscous_W: 120, load_W: 30}
    outputs:                             # displacement channels, µm
      z: {axis: z, sensitivity_um_K: {shaft: 2.0}, tilt_um_K: {housing/column: 1.0}, centrifugal_um: 0.5}
    sensors:                             # temperature sensors read a node, displacement sensors an output
      T_shaft: {node: shaft, lag_s: 30, noise_K: 0.01, offset_K: 0.1, resolution_K: 0.01}
      disp_z: {output: z, noise_um: 0.05}
    mechanisms:                          # applied in order when the network is built (registry ids)
      - {id: centrifugal_growth, params: {um_at_ref: 0.6}}

Named specs live in ``conf/network/<name>.yaml`` (package ``thermodrift.conf.network``), which is also a Hydra
config group, so ``network=vmc_spindle_s2`` composes one into an experiment; pass the composed node to
:func:`network_from_dict`.
"""

from __future__ import annotations

import dataclasses
import importlib.resources
from pathlib import Path
from typing import Any, Mapping, Sequence

import yaml

from thermodrift.core.errors import InputError
from thermodrift.core.physics.network import (SOURCE_TYPES, Advection, Edge, Network, Node, Output,
                                              iter_elements)
from thermodrift.core.physics.sensors import DisplacementSensor, TemperatureSensor

_TOP = ("name", "description", "reference_speed_rpm", "nodes", "edges", "advections", "sources", "outputs",
        "sensors", "mechanisms", "mechanisms_applied")


def schema() -> dict[str, dict[str, dict[str, Any]]]:
    """Every element type's fields: ``{type: {field: {"unit", "default", "min", "max", "doc"}}}``."""
    types = {"node": Node, "edge": Edge, "advection": Advection, "output": Output,
             "temperature_sensor": TemperatureSensor, "displacement_sensor": DisplacementSensor,
             **{f"source:{k}": v for k, v in SOURCE_TYPES.items()}}
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for tname, cls in types.items():
        out[tname] = {}
        for f in dataclasses.fields(cls):
            if f.name == "name":
                continue
            default = f.default if f.default is not dataclasses.MISSING else (
                "{}" if f.default_factory is not dataclasses.MISSING else "required")
            out[tname][f.name] = {"default": default, **{k: v for k, v in f.metadata.items() if v not in (None, "")}}
    return out


def _element(cls: type, name: str, fields: Any, where: str, file: str | None) -> Any:
    """Build one dataclass element from a YAML mapping, naming the element and field on any error."""
    if not isinstance(fields, Mapping):
        raise InputError(f"{where} {name!r} must be a mapping of fields", file=file)
    known = {f.name: f for f in dataclasses.fields(cls)}
    unknown = set(fields) - set(known)
    if unknown:
        raise InputError(f"{where} {name!r}: unknown field(s) {sorted(unknown)}", file=file,
                         hint=f"allowed: {', '.join(k for k in known if k != 'name')}")
    kwargs: dict[str, Any] = {"name": str(name)}
    for key, f in known.items():
        if key == "name":
            continue
        if key not in fields:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise InputError(f"{where} {name!r}: missing field {key!r}", file=file,
                                 hint=f"{key} in {f.metadata.get('unit', '')}".strip())
            continue
        value = fields[key]
        try:
            if "unit" in f.metadata:
                value = float(value)
            elif isinstance(value, Mapping):
                value = {str(k): float(v) for k, v in value.items()}
            else:
                value = str(value)
        except (TypeError, ValueError):
            raise InputError(f"{where} {name!r}: field {key!r} must be a number "
                             f"({f.metadata.get('unit', 'mapping of numbers')}), got {value!r}", file=file) from None
        kwargs[key] = value
    return cls(**kwargs)


def network_from_dict(spec: Mapping[str, Any], *, file: str | None = None, apply_mechanisms: bool = True,
                      skip_mechanisms: Sequence[str] = (), registry=None) -> Network:
    """Build and validate a :class:`Network` from a spec mapping (see the module docstring).

    ``mechanisms`` are applied in order through the mechanism registry (``registry`` or the default one) unless
    ``apply_mechanisms`` is False; ids in ``skip_mechanisms`` are left out (the baseline a missing-physics test
    hands over); ``mechanisms_applied`` (written by :func:`network_to_dict`) is only recorded.
    """
    if not isinstance(spec, Mapping):
        raise InputError("a network spec must be a mapping", file=file)
    unknown = set(spec) - set(_TOP)
    if unknown:
        raise InputError(f"unknown network spec key(s) {sorted(unknown)}", file=file,
                         hint=f"allowed: {', '.join(_TOP)}")
    name = str(spec.get("name") or (Path(file).stem if file else "network"))

    def section(key: str, kind: type) -> Any:
        value = spec.get(key) or kind()
        if not isinstance(value, kind):
            raise InputError(f"network {name!r}: {key!r} must be a {'list' if kind is list else 'mapping'}", file=file)
        return value

    nodes = tuple(_element(Node, n, f, "node", file) for n, f in section("nodes", dict).items())
    edges = []
    for i, f in enumerate(section("edges", list)):
        f = dict(f) if isinstance(f, Mapping) else f
        ename = f.pop("name", f"{f.get('a')}-{f.get('b')}") if isinstance(f, dict) else f"#{i}"
        edges.append(_element(Edge, ename, f, "edge", file))
    advections = []
    for f in section("advections", list):
        f = dict(f) if isinstance(f, Mapping) else f
        aname = f.pop("name", f"{f.get('upstream')}->{f.get('downstream')}") if isinstance(f, dict) else "?"
        advections.append(_element(Advection, aname, f, "advection", file))
    sources = []
    for sname, f in section("sources", dict).items():
        f = dict(f) if isinstance(f, Mapping) else {}
        stype = f.pop("type", None)
        if stype not in SOURCE_TYPES:
            raise InputError(f"source {sname!r}: type {stype!r} is unknown", file=file,
                             hint=f"use one of {', '.join(SOURCE_TYPES)}")
        sources.append(_element(SOURCE_TYPES[stype], sname, f, f"{stype} source", file))
    outputs = tuple(_element(Output, n, f, "output", file) for n, f in section("outputs", dict).items())
    sensors = []
    for sname, f in section("sensors", dict).items():
        cls = DisplacementSensor if isinstance(f, Mapping) and "output" in f else TemperatureSensor
        sensor = _element(cls, sname, f, "sensor", file)
        sensors.append(sensor)
    try:
        n_ref = float(spec.get("reference_speed_rpm", 5000.0))
    except (TypeError, ValueError):
        raise InputError(f"network {name!r}: reference_speed_rpm must be a number (rpm)", file=file) from None
    if n_ref <= 0:
        raise InputError(f"network {name!r}: reference_speed_rpm must be positive (rpm)", file=file)
    net = Network(name=name, nodes=nodes, edges=tuple(edges), advections=tuple(advections), sources=tuple(sources),
                  outputs=outputs, sensors=tuple(sensors), reference_speed_rpm=n_ref,
                  description=str(spec.get("description", "")),
                  mechanisms=tuple(dict(m) for m in spec.get("mechanisms_applied") or ()))
    net.validate(file)
    if apply_mechanisms:
        chosen = [m for m in section("mechanisms", list)
                  if not (isinstance(m, Mapping) and m.get("id") in skip_mechanisms)]
        net = apply_mechanism_list(net, chosen, file=file, registry=registry)
    return net


def apply_mechanism_list(network: Network, mechanisms: list, *, file: str | None = None, registry=None) -> Network:
    """Apply ``[{id, params?, options?}, ...]`` in order, looking each id up in the mechanism registry."""
    if not mechanisms:
        return network
    if registry is None:
        from thermodrift.core import registry as default_registry
        registry = default_registry.default()
    for entry in mechanisms:
        if not isinstance(entry, Mapping) or "id" not in entry:
            raise InputError(f"network {network.name!r}: each mechanism needs an 'id'", file=file)
        known = registry.names("mechanism")
        if entry["id"] not in known:
            raise InputError(f"unknown mechanism {entry['id']!r}", file=file, hint=f"known: {', '.join(known)}")
        mech = registry.create("mechanism", entry["id"], **dict(entry.get("options") or {}))
        network = mech.apply(network, **dict(entry.get("params") or {}))
    return network.validate(file)


def network_to_dict(network: Network) -> dict[str, Any]:
    """The spec mapping of ``network`` (mechanisms already applied are listed under ``mechanisms_applied``)."""
    out: dict[str, Any] = {"name": network.name, "description": network.description,
                           "reference_speed_rpm": network.reference_speed_rpm,
                           "nodes": {}, "edges": [], "advections": [], "sources": {}, "outputs": {}, "sensors": {}}
    type_of = {cls: key for key, cls in SOURCE_TYPES.items()}
    for coll, e in iter_elements(network):
        fields = {f.name: plain(getattr(e, f.name)) for f in dataclasses.fields(e) if f.name != "name"}
        if coll in ("edges", "advections"):
            out[coll].append({"name": e.name, **fields})
        elif coll == "sources":
            out[coll][e.name] = {"type": type_of[type(e)], **fields}
        else:
            out[coll][e.name] = fields
    out["mechanisms_applied"] = [plain(m) for m in network.mechanisms]
    return out


def plain(value: Any) -> Any:
    """``value`` with tuples as lists and mapping keys as strings (YAML/JSON-ready)."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


def load_network(source: str | Path, *, apply_mechanisms: bool = True, skip_mechanisms: Sequence[str] = (),
                 registry=None) -> Network:
    """Load a network from a YAML file path or a named spec in ``conf/network`` (e.g. ``"demo_spindle"``).

    ``apply_mechanisms`` and ``skip_mechanisms`` as in :func:`network_from_dict`.
    """
    path = Path(source)
    if path.suffix not in (".yaml", ".yml"):
        path = Path(str(importlib.resources.files("thermodrift.conf.network") / f"{source}.yaml"))
        if not path.is_file():
            raise InputError(f"unknown network {str(source)!r}", hint=f"named networks: {', '.join(network_names())}")
    if not path.is_file():
        raise InputError("network spec not found", file=str(path))
    try:
        spec = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise InputError(f"not valid YAML: {' '.join(str(exc).split())}", file=str(path)) from None
    return network_from_dict(spec, file=str(path), apply_mechanisms=apply_mechanisms,
                             skip_mechanisms=skip_mechanisms, registry=registry)


def network_names() -> list[str]:
    """Names of the specs shipped in ``conf/network``."""
    folder = importlib.resources.files("thermodrift.conf.network")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))
