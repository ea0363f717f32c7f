"""Template: a thermodrift optimizer plugin (an Optuna sampler) in one file.

How to use:
1. Copy this file into your package, e.g. ``my_samplers/local_search.py``, and rename class and registry name.
2. Fill in the ``todo`` parts. Keep the rules: the factory takes ``seed`` (same seed -> same suggestions) and
   returns an ``optuna.samplers.BaseSampler``; suggestions stay inside each parameter's range, step grid and
   choices. Optuna calls ``infer_relative_search_space`` and ``sample_relative`` at a trial's first
   ``suggest_*`` call, then ``sample_independent`` for every parameter the relative step did not cover.
   Threads share one sampler (``n_jobs>1``): derive each draw's randomness from (seed, trial number, name) and
   keep population state in the study's storage, not in the sampler object. A factory that needs the trial
   budget for its schedule takes ``n_trials``.
3. One entry-point line in your ``pyproject.toml``::

       [project.entry-points.thermodrift]
       local_search = "my_samplers.local_search"

4. ``thermodrift run optimizer=local_search`` works with no YAML: its config is built from the registry
   (``params`` = the constructor's defaults). For other defaults ship ``my_samplers/conf/optimizer/local_search.yaml``
   and add ``registry.add_searchpath("pkg://my_samplers.conf")`` in a ``thermodrift_hydra_searchpaths`` hook.
5. Check it: ``from thermodrift.testing import check_component; check_component("optimizer", "local_search")``
   or subclass ``thermodrift.testing.pytest_components.OptimizerTests`` with ``name = "local_search"``.

The example is a local random search: each parameter is drawn near the best trial's value or uniformly.
"""

import math
import zlib

import numpy as np
import optuna
from optuna.distributions import CategoricalDistribution, IntDistribution

from thermodrift.core.hookspecs import hookimpl


# todo: rename the class and describe the algorithm
class LocalRandomSearch(optuna.samplers.BaseSampler):
    """With probability ``exploit`` a parameter is drawn around the best trial's value (a normal step of
    ``sigma`` in the unit interval of its range), otherwise uniformly over its range."""

    # todo: the seed first, then the algorithm's settings with defaults
    def __init__(self, seed: int | None = None, exploit: float = 0.5, sigma: float = 0.1):
        self.seed = seed
        self.exploit = exploit
        self.sigma = sigma
        self._entropy = seed if seed is not None else int(np.random.SeedSequence().entropy % 2**63)

    # todo: at least two cheap settings for the conformance suite
    @classmethod
    def get_test_params(cls):
        return [{"exploit": 0.5}, {"exploit": 0.9, "sigma": 0.05}]

    # todo: a joint (relative) proposal over several parameters goes here; this example has none
    def infer_relative_search_space(self, study, trial):
        return {}

    def sample_relative(self, study, trial, search_space):
        return {}

    # todo: the per-parameter proposal
    def sample_independent(self, study, trial, param_name, param_distribution):
        rng = np.random.default_rng([self._entropy, trial.number, zlib.crc32(param_name.encode())])
        best = _best_trial(study)
        near_best = best is not None and param_name in best.params and rng.random() < self.exploit
        if isinstance(param_distribution, CategoricalDistribution):
            if near_best:
                return best.params[param_name]
            return param_distribution.choices[int(rng.integers(len(param_distribution.choices)))]
        u = rng.random()
        if near_best:
            u = _to_unit(param_distribution, best.params[param_name]) + self.sigma * rng.normal()
        return _from_unit(param_distribution, float(np.clip(u, 0.0, 1.0)))


def _best_trial(study):
    try:
        return study.best_trial
    except ValueError:  # no complete trial yet
        return None


def _to_unit(dist, value):
    low, high, value = (math.log(v) for v in (dist.low, dist.high, value)) if dist.log else (dist.low, dist.high, value)
    return (value - low) / (high - low) if high > low else 0.0


def _from_unit(dist, u):
    if dist.log:
        value = math.exp(math.log(dist.low) + u * (math.log(dist.high) - math.log(dist.low)))
    else:
        value = dist.low + u * (dist.high - dist.low)
    if dist.step is not None:  # snap to the grid low + k*step, never past high
        k_max = math.floor((dist.high - dist.low) / dist.step + 1e-9)
        value = dist.low + min(round((value - dist.low) / dist.step), k_max) * dist.step
    if isinstance(dist, IntDistribution):
        return int(min(max(round(value), dist.low), dist.high))
    return float(min(max(value, dist.low), dist.high))


# todo: the registry name users type in `thermodrift run optimizer=<name>`
@hookimpl
def thermodrift_register_optimizers(registry):
    registry.add("optimizer", "local_search", LocalRandomSearch)

