"""Optuna's own samplers exposed through the registry: ``random``, ``tpe``, ``cmaes`` and ``gp``."""

import optuna

from thermodrift.core.hookspecs import hookimpl


def random(seed: int | None = None) -> optuna.samplers.BaseSampler:
    """Uniform random search."""
    return optuna.samplers.RandomSampler(seed=seed)


def tpe(seed: int | None = None, n_startup_trials: int = 10, multivariate: bool = True) -> optuna.samplers.BaseSampler:
    """Tree-structured Parzen estimator (Optuna 5 defaults: multivariate, constant liar)."""
    return optuna.samplers.TPESampler(seed=seed, n_startup_trials=n_startup_trials, multivariate=multivariate)


def cmaes(seed: int | None = None, n_startup_trials: int = 1, restart_strategy: str | None = None
          ) -> optuna.samplers.BaseSampler:
    """CMA-ES (categorical parameters fall back to random sampling)."""
    return optuna.samplers.CmaEsSampler(seed=seed, n_startup_trials=n_startup_trials,
                                        restart_strategy=restart_strategy, warn_independent_sampling=False)


def gp(seed: int | None = None, n_startup_trials: int = 10) -> optuna.samplers.BaseSampler:
    """Gaussian-process Bayesian optimisation (Optuna's GPSampler, torch + scipy)."""
    return optuna.samplers.GPSampler(seed=seed, n_startup_trials=n_startup_trials)


@hookimpl
def thermodrift_register_optimizers(registry):
    for factory in (random, tpe, cmaes, gp):
        registry.add("optimizer", factory.__name__, factory)
