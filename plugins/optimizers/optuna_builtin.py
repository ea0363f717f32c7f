"""Optuna's own samplers exposed through the registry: ``random``, ``tpe``, ``cmaes`` and ``gp``.

Every worker of one study (processes or machines sharing its storage) builds its sampler with the same ``seed``,
and Optuna's samplers draw from that seed alone, so the workers would repeat each other's draws. Each sampler
here therefore keeps ``seed`` when the first trial it asks in a study is the study's trial 0 (one worker, or the
worker that started first: exactly Optuna's sequence for that seed) and otherwise, before its first draw, is
seeded again from ``(seed, n)``, ``n`` being that first trial's number. The storage hands out trial numbers
uniquely, so every worker gets its own stream without coordination, as the population samplers derive theirs
from ``(seed, trial number)``; a resumed study draws new points too instead of replaying the earlier run's.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import optuna
from optuna.trial import FrozenTrial

from thermodrift.core.hookspecs import hookimpl


class _WorkerStreams:
    """Mixin over an Optuna sampler class: the worker-specific stream of the module docstring."""

    def __init__(self, seed: int | None = None, **params: Any) -> None:
        super().__init__(seed=seed, **params)
        self._given = (seed, params)
        self._studies: set[str] = set()

    def before_trial(self, study: optuna.Study, trial: FrozenTrial) -> None:
        if study.study_name not in self._studies:
            self._studies.add(study.study_name)
            seed, params = self._given
            if seed is not None and trial.number > 0:  # another worker (or an earlier run) started the study
                stream = int(np.random.SeedSequence([seed, trial.number]).generate_state(1)[0])
                studies = self._studies
                with warnings.catch_warnings():  # an experimental argument (TPE's group) was warned about once
                    warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                    super().__init__(seed=stream, **params)  # the sampler afresh on its own stream
                self._studies = studies
        super().before_trial(study, trial)


class RandomSampler(_WorkerStreams, optuna.samplers.RandomSampler):
    """Optuna's RandomSampler with a worker-specific stream."""


class TPESampler(_WorkerStreams, optuna.samplers.TPESampler):
    """Optuna's TPESampler with a worker-specific stream."""


class CmaEsSampler(_WorkerStreams, optuna.samplers.CmaEsSampler):
    """Optuna's CmaEsSampler with a worker-specific stream."""


class GPSampler(_WorkerStreams, optuna.samplers.GPSampler):
    """Optuna's GPSampler with a worker-specific stream."""


def random(seed: int | None = None) -> optuna.samplers.BaseSampler:
    """Uniform random search."""
    return RandomSampler(seed=seed)


def tpe(seed: int | None = None, n_startup_trials: int = 10, multivariate: bool = True, group: bool = False
        ) -> optuna.samplers.BaseSampler:
    """Tree-structured Parzen estimator (Optuna 5 defaults: multivariate, constant liar). ``group`` samples each
    conditional branch of a space (as AutoML's families) on its own."""
    return TPESampler(seed=seed, n_startup_trials=n_startup_trials, multivariate=multivariate, group=group)


def cmaes(seed: int | None = None, n_startup_trials: int = 1, restart_strategy: str | None = None
          ) -> optuna.samplers.BaseSampler:
    """CMA-ES (categorical parameters fall back to random sampling)."""
    return CmaEsSampler(seed=seed, n_startup_trials=n_startup_trials, restart_strategy=restart_strategy,
                        warn_independent_sampling=False)


def gp(seed: int | None = None, n_startup_trials: int = 10) -> optuna.samplers.BaseSampler:
    """Gaussian-process Bayesian optimisation (Optuna's GPSampler, torch + scipy)."""
    return GPSampler(seed=seed, n_startup_trials=n_startup_trials)


@hookimpl
def thermodrift_register_optimizers(registry):
    for factory in (random, tpe, cmaes, gp):
        registry.add("optimizer", factory.__name__, factory)
