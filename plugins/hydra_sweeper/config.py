"""The sweeper's structured config, stored in Hydra's ConfigStore as ``hydra/sweeper=thermodrift``."""

from dataclasses import dataclass, field
from typing import Any, Dict, Optional

from hydra.core.config_store import ConfigStore


@dataclass
class ThermodriftSweeperConf:
    """Settings of ``hydra/sweeper=thermodrift``.

    ``params`` maps config keys to Hydra override syntax: ``interval(-5.0, 5.0)``, ``int(interval(1, 64))``,
    ``range(1, 10)``, ``choice(relu, tanh)`` or ``relu,tanh``, ``tag(log, interval(1e-4, 1e-1))``; any other
    value is passed to every job unchanged. The task function's return value is the objective: a number, or a
    sequence of numbers when ``direction`` is a list (multi-objective).
    """

    _target_: str = "hydra_plugins.thermodrift_sweeper.sweeper.ThermodriftSweeper"
    sampler: str = "tpe"  # a registered optimizer (`thermodrift plugins`): tpe, random, cmaes, pso, rbmox, ...
    sampler_params: Dict[str, Any] = field(default_factory=dict)  # its constructor arguments
    seed: int = 0
    direction: Any = "minimize"  # "minimize" | "maximize" | a list of them
    study_name: Optional[str] = None  # None: the Hydra job name (the app's file name)
    storage: Optional[str] = None  # None: in memory; an RDB URL (sqlite:///sweep.db) makes the sweep resumable
    n_trials: int = 20  # the study's total budget of finished trials, counting those of earlier runs
    n_jobs: int = 1  # trials launched per batch (run in parallel by a parallel launcher)
    params: Dict[str, Any] = field(default_factory=dict)
    # Dotted path of fn(cfg, trial) called after `params` are sampled; it may suggest more (e.g. conditional)
    # parameters with trial.suggest_*, which reach the job as overrides too.
    custom_search_space: Optional[str] = None


def store() -> None:
    """Store the config as ``hydra/sweeper/thermodrift`` (Hydra's plugin scan does so by importing this module)."""
    ConfigStore.instance().store(group="hydra/sweeper", name="thermodrift", node=ThermodriftSweeperConf,
                                 provider="thermodrift")


store()
