"""Contract checks for optimizers: factories ``f(seed=..., **params)`` that return an Optuna sampler.

The checks run short studies on a cheap objective over a mixed space (linear, log and stepped floats, plain and
stepped ints, a categorical). A factory that accepts ``n_trials`` (samplers whose schedules need the budget)
is given the study's budget.
"""

from __future__ import annotations

import inspect
import math
from typing import Any

import optuna

from thermodrift.core.search_space import suggest
from thermodrift.testing import _optuna
from thermodrift.testing.estimator_checks import Factory

N_TRIALS = 12  # past the first generation of a small population and the startup trials of TPE/GP
SPACE: dict[str, dict[str, Any]] = {
    "x": {"type": "float", "low": -2.0, "high": 3.0},
    "lr": {"type": "float", "low": 1e-5, "high": 1e-1, "log": True},
    "dropout": {"type": "float", "low": 0.0, "high": 0.5, "step": 0.1},
    "units": {"type": "int", "low": 1, "high": 64},
    "window": {"type": "int", "low": 2, "high": 10, "step": 2},
    "act": {"type": "categorical", "choices": ["relu", "tanh", "gelu"]},
}


def _objective(trial: optuna.Trial) -> float:
    p = suggest(trial, SPACE)
    return ((p["x"] - 1.0) ** 2 + (math.log10(p["lr"]) + 3.0) ** 2 + (p["dropout"] - 0.2) ** 2
            + ((p["units"] - 20) / 20) ** 2 + ((p["window"] - 6) / 4) ** 2 + (p["act"] != "tanh"))


def _sampler(factory: Factory, params: dict) -> optuna.samplers.BaseSampler:
    kwargs = dict(params)
    if not _accepts(factory, "seed"):
        raise AssertionError("the factory must accept seed=...; every random thing takes a seed")
    if "n_trials" not in kwargs and _names_param(factory, "n_trials"):
        kwargs["n_trials"] = N_TRIALS
    return factory(seed=0, **kwargs)


def _parameters(factory: Factory) -> list[inspect.Parameter] | None:
    try:
        return list(inspect.signature(factory).parameters.values())
    except (TypeError, ValueError):  # no introspectable signature: let the call decide
        return None


def _accepts(factory: Factory, name: str) -> bool:
    params = _parameters(factory)
    return params is None or any(p.name == name or p.kind is p.VAR_KEYWORD for p in params)


def _names_param(factory: Factory, name: str) -> bool:
    return any(p.name == name for p in _parameters(factory) or ())


def _trials(factory: Factory, params: dict) -> list[optuna.trial.FrozenTrial]:
    """The trials of one seeded study; the budget and the search-space check share it (GP/TPE take seconds)."""
    key = (factory, repr(sorted(params.items())))
    if key not in _STUDIES:
        _STUDIES.clear()
        _STUDIES[key] = _run_study(factory, params)
    return _STUDIES[key]


_STUDIES: dict[tuple, list[optuna.trial.FrozenTrial]] = {}


def _run_study(factory: Factory, params: dict) -> list[optuna.trial.FrozenTrial]:
    with _optuna.quiet():
        study = optuna.create_study(sampler=_sampler(factory, params))
        study.optimize(_objective, n_trials=N_TRIALS)
    return study.trials


def check_returns_sampler(factory: Factory, params: dict) -> None:
    """``factory(seed=0, **params)`` returns an ``optuna.samplers.BaseSampler``."""
    sampler = _sampler(factory, params)
    assert isinstance(sampler, optuna.samplers.BaseSampler), (
        f"factory returned {type(sampler).__name__}, not an optuna.samplers.BaseSampler")


def check_respects_budget(factory: Factory, params: dict) -> None:
    """A study with ``n_trials=N`` runs exactly N trials, all of them complete."""
    states = [t.state.name for t in _trials(factory, params)]
    assert len(states) == N_TRIALS, f"optimize(n_trials={N_TRIALS}) ran {len(states)} trials"
    assert set(states) == {"COMPLETE"}, f"trial states {states}; every trial of a valid objective must complete"


def check_respects_search_space(factory: Factory, params: dict) -> None:
    """Every suggested value lies inside its bounds, on its step grid, or among its choices."""
    for trial in _trials(factory, params):
        for name, value in trial.params.items():
            problem = _outside(SPACE[name], value)
            assert problem is None, f"trial {trial.number}: {name}={value!r} {problem}"


def _outside(spec: dict[str, Any], value: Any) -> str | None:
    if spec["type"] == "categorical":
        return None if value in spec["choices"] else f"is not one of {spec['choices']}"
    low, high, step = spec["low"], spec["high"], spec.get("step")
    if spec["type"] == "int" and (not isinstance(value, int) or isinstance(value, bool)):
        return "is not an int"
    if not low <= value <= high:
        return f"is outside [{low}, {high}]"
    if step is not None and not math.isclose((value - low) / step, round((value - low) / step), abs_tol=1e-8):
        return f"is off the grid {low} + k*{step}"
    return None


def check_seed_reproducible(factory: Factory, params: dict) -> None:
    """Two studies with ``seed=0`` suggest the same parameters trial by trial."""
    first = [t.params for t in _trials(factory, params)]
    second = [t.params for t in _run_study(factory, params)]
    differ = [i for i, (a, b) in enumerate(zip(first, second)) if a != b]
    if differ:
        i = differ[0]
        raise AssertionError(f"same seed, different suggestions from trial {i}: {first[i]} vs {second[i]}")


OPTIMIZER_CHECKS = (check_returns_sampler, check_respects_budget, check_respects_search_space, check_seed_reproducible)
