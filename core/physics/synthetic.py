"""Synthetic recordings with ground truth: simulate a network, give its sensors realistic errors, keep the truth.

:func:`synthesize` draws one fixed offset per temperature sensor from the Pt100 tolerance class (IEC 60751:
class A ±(0.15 + 0.002|t|) °C, class B ±(0.3 + 0.005|t|) °C), simulates, adds white noise and quantization and
returns the :class:`Recording` together with a JSON-ready ``truth`` (the full network spec after mechanisms,
the mechanisms with their parameters, the drawn offsets, the scenario and the seed). The same seed gives the
same recording, bit for bit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from thermodrift.core.physics.integrate import CompiledNetwork, SimulationResult, simulate
from thermodrift.core.physics.network import Network
from thermodrift.core.physics.scenarios import Block, Scenario, blocks
from thermodrift.core.physics.spec import network_from_dict, network_to_dict

PT100_TOLERANCE = {"A": (0.15, 0.002), "B": (0.3, 0.005)}  # (K, 1/K·|t|)


@dataclass
class Synthetic:
    """A simulated recording, the simulation behind it and its ground truth (JSON-ready)."""

    recording: Any
    result: SimulationResult
    truth: dict[str, Any]


def draw_sensor_offsets(network: Network, seed: int, tolerance_class: str = "A",
                        at_degC: float = 25.0) -> Network:
    """A copy whose temperature sensors carry a fixed offset drawn within the Pt100 tolerance class.

    Offsets are normal with σ = tolerance/2, clipped to ± tolerance (most sensors sit well inside their class).
    """
    base, slope = PT100_TOLERANCE[tolerance_class]
    tol = base + slope * abs(at_degC)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    sensors = network.temperature_sensors
    draws = np.clip(rng.normal(0.0, tol / 2, len(sensors)), -tol, tol)
    return network.replace(*[dataclasses.replace(s, offset_K=round(s.offset_K + float(d), 4))
                             for s, d in zip(sensors, draws)])


def synthesize(network: Network, scenario: Scenario, seed: int = 0, *, tolerance_class: str | None = "A",
               source: str | None = None) -> Synthetic:
    """Simulate ``network`` over ``scenario`` and measure it with seeded sensor offsets and noise."""
    if tolerance_class is not None:
        network = draw_sensor_offsets(network, seed, tolerance_class)
    compiled = CompiledNetwork(network)
    result = simulate(compiled, scenario)
    noise_seed = int(np.random.SeedSequence([seed, 2]).generate_state(1)[0])
    recording = result.to_recording(seed=noise_seed, source=source or f"simulated:{network.name}")
    truth = {
        "network": network_to_dict(network),
        "mechanisms": [dict(m) for m in network.mechanisms],
        "sensor_offsets_K": {s.name: s.offset_K for s in network.temperature_sensors},
        "scenario": {"name": scenario.name, "dt_s": scenario.dt_s, "hours": round(scenario.hours, 6),
                     "samples": len(scenario)},
        "seed": seed,
        "time_constants_h_at_rest": [round(float(t) / 3600.0, 4) for t in compiled.time_constants_s(0.0)],
    }
    return Synthetic(recording, result, truth)


# Speed-driven heat only, inside the auto network's family: four nodes (h unmeasured), Pt100 offsets. The null
# case of calibration (nothing missing) shared by its tests and the physics benchmark.
SPEED_ONLY = {
    "name": "speed_only", "reference_speed_rpm": 5000,
    "nodes": {n: {"capacity_J_K": 1e4} for n in ("front", "rear", "housing", "h")},
    "edges": [{"a": n, "b": "ambient", "G_W_K": g, "kind": "convection"}
              for n, g in (("front", 4.0), ("rear", 6.0), ("housing", 3.0), ("h", 1.5))],
    "sources": {f"q_{n}": {"type": "bearing", "node": n, "viscous_W": q, "viscous_exponent": 1.4}
                for n, q in (("front", 40.0), ("rear", 30.0), ("housing", 10.0), ("h", 6.0))},
    "outputs": {"z": {"axis": "z", "sensitivity_um_K": {"front": 1.0, "housing": 2.0, "h": 3.0}}},
    "sensors": {"T_front": {"node": "front", "noise_K": 0.02, "offset_K": 0.3},
                "T_rear": {"node": "rear", "noise_K": 0.02, "offset_K": -0.2},
                "T_housing": {"node": "housing", "noise_K": 0.02}, "dz": {"output": "z", "noise_um": 0.1}},
}


def speed_only(seed: int, dt_s: float = 15.0, repeats: int = 1) -> Synthetic:
    """:data:`SPEED_ONLY` run through 1250, 2500, 5000 and 3500 rpm (3 h each, 2 h stops), ``repeats`` times,
    sampled every ``dt_s`` s."""
    prog = [Block(0.5)] + [b for n in (1250, 2500, 5000, 3500) for b in (Block(3.0, n), Block(2.0))] * repeats
    return synthesize(network_from_dict(SPEED_ONLY), blocks(prog, dt_s), seed)
