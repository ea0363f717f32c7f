"""The Hydra plugin class. Hydra imports every plugin module at start-up, so Optuna and thermodrift are
imported only when a sweep runs (see ``_sweep.py``)."""

from typing import Any, List, Optional

from omegaconf import DictConfig, ListConfig, OmegaConf

from hydra.core.plugins import Plugins
from hydra.plugins.launcher import Launcher
from hydra.plugins.sweeper import Sweeper
from hydra.types import HydraContext, TaskFunction


class ThermodriftSweeper(Sweeper):
    """Asks an Optuna study for trials, launches them as Hydra jobs in batches, tells it the jobs' returns."""

    def __init__(self, sampler: str, sampler_params: Any, seed: int, direction: Any, study_name: Optional[str],
                 storage: Optional[str], n_trials: int, n_jobs: int, params: Any,
                 custom_search_space: Optional[str]) -> None:
        if n_trials < 0 or n_jobs < 1:
            raise ValueError(f"hydra.sweeper: need n_trials >= 0 and n_jobs >= 1, got {n_trials} and {n_jobs}")
        self.sampler = sampler
        self.sampler_params = _plain(sampler_params) or {}
        self.seed = seed
        direction = _plain(direction)
        self.directions = [direction] if isinstance(direction, str) else list(direction)
        self.study_name = study_name
        self.storage = storage
        self.n_trials = n_trials
        self.n_jobs = n_jobs
        self.params = _plain(params) or {}
        self.custom_search_space = custom_search_space
        self.hydra_context: Optional[HydraContext] = None
        self.config: Optional[DictConfig] = None
        self.launcher: Optional[Launcher] = None

    def setup(self, *, hydra_context: HydraContext, task_function: TaskFunction, config: DictConfig) -> None:
        self.hydra_context = hydra_context
        self.config = config
        self.launcher = Plugins.instance().instantiate_launcher(
            hydra_context=hydra_context, task_function=task_function, config=config)

    def sweep(self, arguments: List[str]) -> None:
        from hydra_plugins.thermodrift_sweeper._sweep import run_sweep

        run_sweep(self, arguments)


def _plain(value: Any) -> Any:
    return OmegaConf.to_container(value, resolve=True) if isinstance(value, (DictConfig, ListConfig)) else value
