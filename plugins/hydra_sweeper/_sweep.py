"""The sweep loop: ask a batch of trials, launch them as Hydra jobs, tell the study what they returned."""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import optuna
from omegaconf import OmegaConf
from optuna.trial import TrialState

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.utils import JobReturn
from hydra.utils import get_method

from hydra_plugins.thermodrift_sweeper import _search_space

if TYPE_CHECKING:
    from hydra_plugins.thermodrift_sweeper.sweeper import ThermodriftSweeper

log = logging.getLogger(__name__)
_FINISHED = (TrialState.COMPLETE, TrialState.PRUNED, TrialState.FAIL)


def run_sweep(sweeper: ThermodriftSweeper, arguments: list[str]) -> None:
    """Run trials until the study holds ``n_trials`` finished ones, then write ``optimization_results.yaml``."""
    assert sweeper.config is not None and sweeper.launcher is not None and sweeper.hydra_context is not None
    config = sweeper.config
    parser = OverridesParser.create(config_loader=sweeper.hydra_context.config_loader)
    space = _search_space.parse(sweeper.params, arguments, parser)
    extend = get_method(sweeper.custom_search_space) if sweeper.custom_search_space else None
    # Compose the search space's corners once, not every trial's config: a bad key or type fails here, before
    # any job runs, and each trial costs one composition (the launcher's) instead of two.
    sweeper.validate_batch_is_legal(space.corner_overrides())
    study = optuna.create_study(
        study_name=sweeper.study_name or config.hydra.job.name,
        storage=sweeper.storage, load_if_exists=True, directions=sweeper.directions,
        sampler=create_sampler(sweeper.sampler, sweeper.sampler_params, sweeper.seed, sweeper.n_trials))

    sweep_dir = Path(config.hydra.sweep.dir)
    sweep_dir.mkdir(parents=True, exist_ok=True)
    OmegaConf.save(config, sweep_dir / "multirun.yaml")
    done = _n_finished(study)
    log.info("Study %r, sampler %s (seed %d), %s: %d of %d trials finished; search space %s; fixed %s",
             study.study_name, sweeper.sampler, sweeper.seed, "/".join(sweeper.directions), done,
             sweeper.n_trials, space.distributions, space.fixed)

    job_idx = 0
    while done < sweeper.n_trials:
        trials = [study.ask(space.distributions) for _ in range(min(sweeper.n_jobs, sweeper.n_trials - done))]
        try:
            if extend is not None:
                for trial in trials:
                    extend(config, trial)
            batch = [space.overrides(trial.params) for trial in trials]
            results = sweeper.launcher.launch(batch, initial_job_idx=job_idx)
        except BaseException as exc:  # a job config that does not compose, or Ctrl-C: no trial stays RUNNING
            for trial in trials:
                trial.set_user_attr("failure", _one_line(exc))
                study.tell(trial, state=TrialState.FAIL)
            raise
        job_idx += len(batch)
        for trial, result in zip(trials, results):
            _tell(study, trial, result)
        done = _n_finished(study)

    _write_results(study, sweeper.sampler, sweep_dir / "optimization_results.yaml")


def create_sampler(name: str, params: dict[str, Any], seed: int, n_trials: int) -> optuna.samplers.BaseSampler:
    """The registered optimizer ``name``; samplers whose schedules need the budget also get ``n_trials``."""
    from thermodrift.core import registry

    return registry.create_sampler(name, seed=seed, n_trials=n_trials, **params)


def objective_values(returned: Any, n_objectives: int) -> list[float]:
    """The task's return value as finite floats, one per objective; ValueError if it is not that."""
    several = isinstance(returned, (Sequence, np.ndarray)) and not isinstance(returned, str)
    items = list(returned) if several else [returned]
    try:
        if any(isinstance(v, (str, bytes)) for v in items):
            raise TypeError
        values = [float(v) for v in items]
    except (TypeError, ValueError):
        raise ValueError(f"the task returned {returned!r}, not a number per objective") from None
    if len(values) != n_objectives:
        raise ValueError(f"the task returned {len(values)} values for {n_objectives} objective(s)")
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"the task returned a non-finite objective {values}")
    return values


def _tell(study: optuna.Study, trial: optuna.Trial, result: JobReturn) -> None:
    try:
        values = objective_values(result.return_value, len(study.directions))  # re-raises the job's exception
    except Exception as exc:  # any failing job is recorded as FAIL and the sweep goes on
        reason = _one_line(exc)
        trial.set_user_attr("failure", reason)
        study.tell(trial, state=TrialState.FAIL)
        log.warning("Trial %d failed (%s) with %s", trial.number, reason, trial.params)
        return
    study.tell(trial, values)


def _one_line(exc: BaseException) -> str:
    return " ".join(f"{type(exc).__name__}: {exc}".split())


def _n_finished(study: optuna.Study) -> int:
    return len(study.get_trials(deepcopy=False, states=_FINISHED))


def _write_results(study: optuna.Study, sampler: str, path: Path) -> None:
    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    results: dict[str, Any] = {
        "study_name": study.study_name, "sampler": sampler,
        "directions": [d.name.lower() for d in study.directions],
        "n_complete": len(complete), "n_failed": len(study.get_trials(deepcopy=False, states=(TrialState.FAIL,))),
    }
    if complete and len(study.directions) == 1:
        results.update(best_params=study.best_params, best_value=study.best_value)
    elif complete:
        results["best_trials"] = [{"number": t.number, "params": t.params, "values": t.values}
                                  for t in study.best_trials]
    OmegaConf.save(OmegaConf.create(results), path)
    log.info("Best: %s", {k: v for k, v in results.items() if k.startswith("best")} or "no complete trial")
