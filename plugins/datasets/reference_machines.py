"""Simulated reference machines with ground truth, registered as datasets.

=========================  ==========================================================================  =======
name                       what                                                                        default
=========================  ==========================================================================  =======
``demo_spindle``           5-node belt-driven spindle, 5 temperatures + ambient, Z and X drift;         1,681 × 30 s
                           1500/3000/4500/6000 rpm for 2 h with 1.5 h cool-downs (generated in ms)
``turning_centre_s1``      lathe like study S1: 19 Pt100 points, radial error of turned diameters;       2,302 × 68.6 s
                           the 3 h cut / 1 h stop / 4 h cut duty under the study's three ambient
                           conditions, then the validation cycle
``vmc_spindle_s2``         VMC spindle like S2: 16 magnetic sensors, Z drift; 16,000 s idle warm-ups   12,161 × 10 s
                           at 2000/4000/6000/8000 rpm with 4 h cool-downs (``scenario="s2_warmup"``:
                           the study's single 16,000 s warm-up at 1 s)
``motorized_spindle_s3``   motorized spindle like S3: 16 sensors incl. coolant inlet/outlet and         4,682 × 60 s
                           ambient, Z drift; 4 speed plateaus, daily ambient, on/off chiller
=========================  ==========================================================================  =======

Each factory takes ``seed`` (sensor offsets and noise), ``scenario`` (a name from
:data:`thermodrift.core.physics.scenarios.SCENARIOS`), ``hours`` (keep the first hours) and ``dt_s``, and returns
a :class:`~thermodrift.core.recording.Recording` with a ``condition`` channel. ``factory.generate(...)`` also
returns the simulation and the ground truth (network after mechanisms, offsets, scenario).
Networks: ``conf/network/<name>.yaml``.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from thermodrift.core.errors import InputError
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics import scenarios
from thermodrift.core.physics.spec import load_network
from thermodrift.core.physics.synthetic import Synthetic, synthesize


@lru_cache(maxsize=None)
def _network(name: str):
    return load_network(name)  # networks are immutable, so one parse per process is enough


class ReferenceMachine:
    """Dataset factory for one simulated machine: ``machine(seed=0, scenario=None, hours=None, dt_s=None)``."""

    def __init__(self, name: str, scenario: str, dt_s: float, description: str):
        self.name, self.scenario, self.dt_s, self.description = name, scenario, dt_s, description

    def __repr__(self) -> str:
        return f"ReferenceMachine({self.name!r})"

    def __call__(self, seed: int = 0, scenario: str | None = None, hours: float | None = None,
                 dt_s: float | None = None) -> Any:
        return self.generate(seed, scenario, hours, dt_s).recording

    def generate(self, seed: int = 0, scenario: str | None = None, hours: float | None = None,
                 dt_s: float | None = None) -> Synthetic:
        """The recording with its simulation and ground truth."""
        name = scenario or self.scenario
        kwargs = {"dt_s": float(dt_s)} if dt_s else ({"dt_s": self.dt_s} if name == self.scenario else {})
        scen = scenarios.build(name, **kwargs)
        if hours is not None:
            if hours <= 0:
                raise InputError(f"dataset {self.name!r}: hours must be positive")
            scen = scen.head(float(hours))
        synthetic = synthesize(_network(self.name), scen, int(seed), source=f"{self.name}[seed={seed},{name}]")
        synthetic.truth["machine"] = self.name
        return synthetic

    def get_test_params(self) -> list[dict[str, Any]]:
        return [{"seed": 0, "hours": 4.0}, {"seed": 1, "hours": 2.0}]


MACHINES = {
    "demo_spindle": ReferenceMachine("demo_spindle", "demo", 30.0, "small spindle demo, 4 speed blocks"),
    "turning_centre_s1": ReferenceMachine("turning_centre_s1", "s1_conditions", 8 * 3600 / 420,
                                          "turning centre like study S1, 19 Pt100 points"),
    "vmc_spindle_s2": ReferenceMachine("vmc_spindle_s2", "s2_speed_steps", 10.0,
                                       "VMC spindle like study S2, 16 magnetic sensors"),
    "motorized_spindle_s3": ReferenceMachine("motorized_spindle_s3", "s3_programme", 60.0,
                                             "motorized spindle like study S3, coolant and ambient channels"),
}


@hookimpl
def thermodrift_register_datasets(registry):
    for name, machine in MACHINES.items():
        registry.add("dataset", name, machine)
