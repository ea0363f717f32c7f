"""Concealed-effect recordings for proving the finder: a known mechanism hidden from the baseline.

:func:`programme` draws a seeded ~30 h programme that exercises every driver (speed steps, plateaus and stops,
cutting, axis motion with the spindle idle, chiller cycling, a daily ambient cycle). :func:`random_network`
draws a network of another shape and size than the reference machines. :func:`concealed_case` adds one
mechanism (at a drawn place and magnitude) to a network, simulates the recording with Pt100 offsets and
noise, adds the driver channels a machine would log (ambient, coolant inlet, cutting power, axis velocity)
and hands back the baseline without the mechanism together with the truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from thermodrift.core.physics import scenarios
from thermodrift.core.physics.network import BearingSource, Edge, MotorSource, Network, Node, Output
from thermodrift.core.physics.scenarios import Block, Scenario
from thermodrift.core.physics.sensors import DisplacementSensor, TemperatureSensor
from thermodrift.core.physics.synthetic import synthesize


@dataclass
class Case:
    name: str
    recording: Any
    baseline: Network
    truth: Network
    hidden: str | None            # mechanism id, None for a null case
    params: dict[str, float]
    options: dict[str, Any]
    effect: np.ndarray            # (samples,) |truth − baseline| summed over displacement outputs (µm)
    time_s: np.ndarray


def programme(seed: int, hours: float = 30.0, dt_s: float = 60.0, n_max: float = 6000.0,
              drivers: bool = True) -> Scenario:
    """A seeded programme of about ``hours``: runs at drawn speeds (some cutting), stops, idle axis motion."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 11]))
    blocks: list[Block] = [Block(0.5)]
    total = 0.5
    while total < hours - 1:
        speed = float(rng.choice([0.25, 0.5, 0.75, 1.0])) * n_max
        run_h = float(rng.choice([1.5, 2.0, 3.0]))
        cut = drivers and rng.random() < 0.4
        blocks.append(Block(run_h, speed, cutting_power_W=float(rng.uniform(1500, 4000)) if cut else 0.0))
        stop_h = float(rng.choice([0.5, 1.0, 2.0]))
        axis = drivers and rng.random() < 0.3
        blocks.append(Block(stop_h, 0.0, axis_velocity_mm_min=float(rng.uniform(4000, 9000)) if axis else 0.0))
        total += run_h + stop_h
    ambient = scenarios.daily_cycle(float(rng.uniform(17, 20)), float(rng.uniform(22, 26)),
                                    start_hour=float(rng.uniform(0, 24)))
    coolant = scenarios.chiller_cycling(20.0, float(rng.uniform(0.3, 1.0)), phase=float(rng.random())) \
        if drivers else None
    return scenarios.blocks(blocks, dt_s, ambient=ambient, coolant=coolant, name=f"programme_{seed}")


def random_network(seed: int) -> Network:
    """A network of 4–10 nodes with drawn groups, conductances, heat sources, outputs and sensors."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 12]))
    n = int(rng.integers(4, 11))
    groups = ["bearing", "shaft", "housing", "structure"] + list(rng.choice(
        ["bearing", "motor", "housing", "structure", "table", "structure"], n - 4))
    names = [f"{g}_{i}" for i, g in enumerate(groups)]
    cap = {"bearing": (800, 3000), "shaft": (2000, 8000), "motor": (5000, 15000), "housing": (8000, 40000),
           "structure": (50000, 400000), "table": (30000, 150000)}
    nodes = tuple(Node(nm, float(np.exp(rng.uniform(*np.log(cap[g])))), g) for nm, g in zip(names, groups))
    edges = []
    for i in range(1, n):  # a random spanning tree keeps every node connected
        j = int(rng.integers(0, i))
        edges.append(Edge(f"{names[j]}-{names[i]}", names[j], names[i], float(rng.uniform(2, 20)),
                          kind=str(rng.choice(["conduction", "contact"]))))
    for i in range(n):
        edges.append(Edge(f"{names[i]}-ambient", names[i], "ambient",
                          float(rng.uniform(0.5, 4)) * (3 if groups[i] in ("structure", "table") else 1),
                          kind="convection"))
    sources = [BearingSource(f"heat_{nm}", nm, float(rng.uniform(30, 150)), float(rng.uniform(5, 40)))
               for nm, g in zip(names, groups) if g == "bearing"]
    motors = [nm for nm, g in zip(names, groups) if g == "motor"]
    if motors:
        sources.append(MotorSource("motor", {motors[0]: 1.0}, float(rng.uniform(50, 200))))
    outputs = []
    for axis in ["z"] + (["x"] if rng.random() < 0.5 else []):
        picks = rng.choice(names, size=min(n, int(rng.integers(2, 5))), replace=False)
        outputs.append(Output(axis, axis, {str(p): float(rng.uniform(-3, 8)) for p in picks}))
    sensors = []
    for nm in names:
        if rng.random() < 0.75:
            sensors.append(TemperatureSensor(f"T_{nm}", nm, noise_K=float(rng.uniform(0.01, 0.03)),
                                             lag_s=float(rng.uniform(0, 60)), resolution_K=0.01))
    if not sensors:
        sensors.append(TemperatureSensor(f"T_{names[0]}", names[0]))
    sensors += [DisplacementSensor(f"d_{o.name}", o.name, noise_um=float(rng.uniform(0.05, 0.4))) for o in outputs]
    return Network(f"random_{seed}", nodes, tuple(edges), (), tuple(sources), tuple(outputs), tuple(sensors),
                   reference_speed_rpm=6000.0).validate()


def with_drivers(recording, scenario: Scenario, seed: int, constant_drivers: bool = False):
    """``recording`` plus the driver channels a machine logs: ambient and coolant inlet (°C, 0.02 K noise),
    cutting power (W) and axis velocity (mm/min); with ``constant_drivers`` the last two are kept even if zero."""
    from thermodrift.core.recording import Channel, Recording

    rng = np.random.default_rng(np.random.SeedSequence([seed, 13]))
    data, channels = recording.data.copy(), dict(recording.channels)
    f = scenario.frame
    for col, role in (("ambient_degC", "ambient"), ("coolant_inlet_degC", "coolant_inlet")):
        if col in channels:
            continue
        data[col] = np.round(f[col].to_numpy() + rng.normal(0, 0.02, len(f)), 3)
        channels[col] = Channel(col, role, "degC", {})
    for col, role, unit in (("cutting_power_W", "cutting_power", "W"), ("axis_velocity_mm_min", "axis_velocity",
                                                                       "mm_min")):
        values = f[col].to_numpy()
        if values.any() or constant_drivers:
            data[col] = values
            channels[col] = Channel(col, role, unit, {})
    return Recording(data, channels, recording.source)


def concealed_case(network: Network, hide: str | None, seed: int, *, registry=None, magnitude: float | None = None,
                   dt_s: float = 60.0, hours: float = 30.0, constant_drivers: bool = False,
                   scenario: Scenario | None = None) -> Case:
    """Truth = ``network`` + mechanism ``hide`` at a drawn place and magnitude (×0.5–2 of its default
    amplitude unless ``magnitude``); baseline = ``network``. ``hide`` None: a null case (truth = baseline)."""
    if registry is None:
        from thermodrift.core import registry as reg_module
        registry = reg_module.default()
    rng = np.random.default_rng(np.random.SeedSequence([seed, 14]))
    if scenario is None:
        drivers = not constant_drivers
        scenario = programme(seed, hours, dt_s, drivers=drivers)
    truth, params, options = network, {}, {}
    if hide is not None:
        cls = registry.get("mechanism", hide).factory
        places = cls.places(network)
        if not places:
            raise ValueError(f"{hide} has no place in {network.name}")
        options = dict(places[int(rng.integers(0, len(places)))])
        scale = magnitude if magnitude is not None else float(np.exp(rng.uniform(np.log(0.5), np.log(2.0))))
        params = {}
        for p in cls.parameters:
            if p.neutral == 0.0 and p.default != 0.0:  # an amplitude: scale it, within bounds
                params[p.name] = float(np.clip(p.default * scale, p.low, p.high))
        truth = cls(**options).apply(network, **params)
    syn = synthesize(truth, scenario, seed=seed)
    rec = with_drivers(syn.recording, scenario, seed, constant_drivers)
    from thermodrift.core.physics.integrate import simulate

    yt = simulate(truth, scenario).displacements.to_numpy()
    yb = simulate(network, scenario).displacements.to_numpy() if hide is not None else yt
    effect = np.abs(yt - yb).sum(axis=1)
    return Case(f"{network.name}:{hide or 'none'}:{seed}", rec, network, truth, hide, params, options, effect,
                scenario.time_s)
