"""Contract checks for optimizers: factories ``f(seed=..., **params)`` that return an Optuna sampler.

The checks run short studies on a cheap objective over a mixed space (linear, log and stepped floats, plain and
stepped ints, a categorical). A factory that accepts ``n_trials`` (samplers whose schedules need the budget)
is given the study's budget. Beyond the basic contract they follow ``optuna.testing``'s sampler suite where a
study meets it: failed and pruned trials, enqueued trials and fixed parameters, a search space whose ranges
and parameters change between trials, and a study resumed by a new sampler object.
"""

from __future__ import annotations

import inspect
import math
import warnings
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


SHORT = 8  # trials of the studies below: past a small population's first generation, seconds for GP


def _study(factory: Factory, params: dict, **kwargs: Any) -> optuna.Study:
    return optuna.create_study(sampler=_sampler(factory, params), **kwargs)


def _assert_in_space(trials: list[optuna.trial.FrozenTrial], space: dict[str, dict[str, Any]] = SPACE) -> None:
    for trial in trials:
        for name, value in trial.params.items():
            problem = _outside(space[name], value)
            assert problem is None, f"trial {trial.number}: {name}={value!r} {problem}"


def check_survives_failed_and_pruned_trials(factory: Factory, params: dict) -> None:
    """A study goes on after trials that fail (raise) or are pruned, and the next suggestions stay valid."""
    def objective(trial: optuna.Trial) -> float:
        value = _objective(trial)
        if trial.number % 3 == 1:
            raise ValueError("a failing job")
        if trial.number % 3 == 2:
            raise optuna.TrialPruned()
        return value

    with _optuna.quiet(optuna.logging.ERROR):  # not one warning with a traceback per planned failure
        study = _study(factory, params)
        try:
            study.optimize(objective, n_trials=SHORT, catch=(ValueError,))
        except Exception as exc:
            raise AssertionError(f"the study broke after failed and pruned trials: {type(exc).__name__}: {exc}") from exc
    states = [t.state.name for t in study.trials]
    assert len(states) == SHORT, f"optimize(n_trials={SHORT}) with failing trials ran {len(states)}"
    assert states.count("COMPLETE") == len(range(0, SHORT, 3)), f"trial states {states}"
    _assert_in_space(study.trials)


def check_enqueued_trials_get_their_parameters(factory: Factory, params: dict) -> None:
    """Trials enqueued before and during a study run with exactly the enqueued values; the rest stay valid."""
    first = {"x": 0.5, "lr": 1e-3, "dropout": 0.2, "units": 7, "window": 4, "act": "gelu"}
    later = {"x": -1.5, "units": 60}  # partial: the sampler fills in the other parameters
    with _optuna.quiet():
        study = _study(factory, params)
        study.enqueue_trial(first)
        study.optimize(_objective, n_trials=SHORT // 2)
        study.enqueue_trial(later)
        study.optimize(_objective, n_trials=SHORT - SHORT // 2)
    trials = study.trials
    assert trials[0].params == first, f"enqueued {first}, ran {trials[0].params}"
    queued = trials[SHORT // 2].params
    assert {k: queued[k] for k in later} == later, f"enqueued {later}, ran {queued}"
    assert all(t.state.name == "COMPLETE" for t in trials), [t.state.name for t in trials]
    _assert_in_space(trials)


def check_fixed_parameters_stay_fixed(factory: Factory, params: dict) -> None:
    """Wrapped in Optuna's ``PartialFixedSampler``, the fixed parameters keep their values in every trial."""
    fixed = {"x": 1.0, "act": "tanh"}
    with _optuna.quiet(), warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)  # Optuna marks it experimental
        study = optuna.create_study(sampler=optuna.samplers.PartialFixedSampler(fixed, _sampler(factory, params)))
        study.optimize(_objective, n_trials=SHORT)
    for trial in study.trials:
        assert {k: trial.params[k] for k in fixed} == fixed, f"trial {trial.number}: {trial.params}"
    _assert_in_space(study.trials)


def check_dynamic_search_space(factory: Factory, params: dict) -> None:
    """Ranges that change between trials and parameters that exist only for some choices get valid values."""
    def space_of(number: int, kind: str | None = None) -> dict[str, dict[str, Any]]:
        wide = number < SHORT // 2
        space = {"kind": {"type": "categorical", "choices": ["a", "b"]},
                 "x": {"type": "float", "low": -2.0 if wide else 0.0, "high": 3.0 if wide else 1.0},
                 "units": {"type": "int", "low": 1, "high": 64 if wide else 8}}
        if kind == "b":
            space["depth"] = {"type": "int", "low": 1, "high": 4}
        return space

    def objective(trial: optuna.Trial) -> float:
        kind = trial.suggest_categorical("kind", ["a", "b"])
        p = suggest(trial, {k: v for k, v in space_of(trial.number, kind).items() if k != "kind"})
        return (p["x"] - 0.5) ** 2 + p["units"] / 64 + p.get("depth", 0)

    with _optuna.quiet():
        study = _study(factory, params)
        study.optimize(objective, n_trials=SHORT)
    assert all(t.state.name == "COMPLETE" for t in study.trials), [t.state.name for t in study.trials]
    for trial in study.trials:
        _assert_in_space([trial], space_of(trial.number, trial.params["kind"]))
        assert ("depth" in trial.params) == (trial.params["kind"] == "b"), f"trial {trial.number}: {trial.params}"


def check_resumes_with_a_new_sampler(factory: Factory, params: dict) -> None:
    """A study stopped and loaded again with a new sampler object (as after a killed run) completes its budget
    with valid suggestions."""
    storage = optuna.storages.InMemoryStorage()
    with _optuna.quiet():
        first = _study(factory, params, storage=storage, study_name="resumed")
        first.optimize(_objective, n_trials=SHORT // 2)
        again = _study(factory, params, storage=storage, study_name="resumed", load_if_exists=True)
        again.optimize(_objective, n_trials=SHORT - SHORT // 2)
    trials = again.trials
    assert len(trials) == SHORT and all(t.state.name == "COMPLETE" for t in trials), (
        f"resumed study holds {[t.state.name for t in trials]}")
    _assert_in_space(trials)


OPTIMIZER_CHECKS = (check_returns_sampler, check_respects_budget, check_respects_search_space, check_seed_reproducible,
                    check_survives_failed_and_pruned_trials, check_enqueued_trials_get_their_parameters,
                    check_fixed_parameters_stay_fixed, check_dynamic_search_space, check_resumes_with_a_new_sampler)
