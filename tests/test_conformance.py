"""The conformance suite over every component the registry discovers, built-in and third-party.

Each (component, test-parameter set, check) is one test, e.g. ``test_contract[model-ridge_demo-0-clone]``;
each component's Hydra config is one more. The second half shows that the checks catch broken components,
so a green run means something.
"""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import numpy as np
import optuna
import pandas as pd
import pytest

from thermodrift.core.components import Selector, ThermalModel
from thermodrift.core.registry import CONFIG_GROUPS, Registry, load
from thermodrift.testing import (
    ConformanceError,
    check_cnc_format,
    check_component,
    check_hydra_config,
    check_mechanism,
    check_model,
    check_optimizer,
    check_selector,
    checks,
    compose_config,
    parameter_sets,
)
from thermodrift.testing.dataset_checks import check_returns_recording
from thermodrift.testing.model_checks import (
    MODEL_CHECKS,
    check_fit_predict_shape,
    check_model_deterministic,
    check_predictions_in_um,
    check_search_space,
    check_streaming_equals_batch,
)
from thermodrift.testing.estimator_checks import check_clone, check_constructor_only_stores_params
from thermodrift.testing.optimizer_checks import (
    check_dynamic_search_space,
    check_respects_search_space,
    check_seed_reproducible,
    check_survives_failed_and_pruned_trials,
)
from thermodrift.testing.selector_checks import check_selection_deterministic, check_selection_idempotent
from thermodrift.testing.suite import CHECKS

from support import load_file

REGISTRY = load()
TEMPLATES = Path(__file__).resolve().parents[1] / "docs" / "templates"


def _components(kinds):
    return [pytest.param(kind, name, id=f"{kind}-{name}") for kind in kinds for name in REGISTRY.names(kind)]


def _contract_cases():
    cases = []
    for kind, name in ((k, n) for k in CHECKS for n in REGISTRY.names(k)):
        factory = REGISTRY.get(kind, name).factory
        try:
            sets = parameter_sets(factory)
        except ConformanceError:  # reported by test_get_test_params
            continue
        for i, params in enumerate(sets):
            for check in checks(kind):
                cases.append(pytest.param(factory, params, check,
                                          id=f"{kind}-{name}-{i}-{check.__name__.removeprefix('check_')}"))
    return cases


def test_every_plugin_loads():
    assert REGISTRY.failures == {}


@pytest.mark.parametrize("kind,name", _components(CHECKS))
def test_get_test_params(kind, name):
    sets = parameter_sets(REGISTRY.get(kind, name).factory)
    assert all(isinstance(p, dict) for p in sets) and sets


@pytest.mark.parametrize("factory,params,check", _contract_cases())
def test_contract(factory, params, check):
    check(factory, params)


@pytest.mark.parametrize("kind,name", _components(CONFIG_GROUPS))
def test_hydra_config(kind, name):
    check_hydra_config(kind, name, REGISTRY)


@pytest.mark.parametrize("template,check", [("selector_plugin", check_selector), ("model_plugin", check_model),
                                            ("optimizer_plugin", check_optimizer),
                                            ("mechanism_plugin", check_mechanism),
                                            ("cnc_plugin", check_cnc_format)])
def test_plugin_templates_pass_the_suite(template, check, monkeypatch):
    # the pickle checks import the class by module name
    module = load_file(TEMPLATES / f"{template}.py", f"template_{template}",
                       lambda name, mod: monkeypatch.setitem(sys.modules, name, mod))
    reg = Registry()
    for hook in ("thermodrift_register_selectors", "thermodrift_register_models", "thermodrift_register_optimizers",
                 "thermodrift_register_mechanisms", "thermodrift_register_cnc_formats"):
        if hasattr(module, hook):
            getattr(module, hook)(registry=reg)
    (kind,) = [k for k in ("selector", "model", "optimizer", "mechanism", "cnc") if reg.names(k)]
    check(reg.get(kind, reg.names(kind)[0]).factory)


# --- the checks catch broken components --------------------------------------------------------------------


class _Linear(ThermalModel):
    """Least squares in µm; subclasses break one rule each."""

    def __init__(self, scale: float = 1.0):
        self.scale = scale

    def _fit(self, X, y):
        A = np.column_stack([X.to_numpy(), np.ones(len(X))])
        self.coef_ = np.linalg.lstsq(A, y, rcond=None)[0]

    def _predict(self, X):
        return self.scale * np.column_stack([X.to_numpy(), np.ones(len(X))]) @ self.coef_


class _Millimetres(_Linear):
    def _predict(self, X):
        return super()._predict(X) / 1000.0


class _Unseeded(_Linear):
    def _predict(self, X):
        return super()._predict(X) + np.random.default_rng().normal(0, 1.0, (len(X), self.coef_.shape[1]))


class _FirstChannelOnly(_Linear):
    def _predict(self, X):
        return super()._predict(X)[:, 0]


class _ConvertsInInit(_Linear):
    def __init__(self, scale: float = 1.0):
        self.scale = float(scale) * 2


class _BadSearchSpace(_Linear):
    @classmethod
    def search_space(cls):
        return {"units": {"type": "int", "low": 1, "high": 8}}


class _Diverging(_Linear):
    @classmethod
    def search_space(cls):
        return {"scale": {"type": "float", "low": 1.0, "high": 1e6, "log": True}}

    def _predict(self, X):
        out = super()._predict(X)
        return out if self.scale < 10 else out * np.inf


class _ClaimsNoMemory(_Linear):
    """Smooths its inputs over the rows it is given but declares history_length = 0: streaming breaks."""

    def _predict(self, X):
        return super()._predict(X.expanding().mean())


class _RandomPick(Selector):
    """Selects by hidden global state, as an unseeded generator does: each fit the next column (certain to differ
    between two fits, where a random pick of 2 columns of the tiny recording repeats now and then)."""
    _fits = itertools.count()

    def _select(self, X, y):
        return [X.columns[next(self._fits) % len(X.columns)]]


class _DropsLast(Selector):
    def _select(self, X, y):
        return list(X.columns[:-1]) or list(X.columns)


class _OffGrid(optuna.samplers.RandomSampler):
    def sample_independent(self, study, trial, name, distribution):
        value = super().sample_independent(study, trial, name, distribution)
        return distribution.high + 1 if isinstance(distribution, optuna.distributions.IntDistribution) else value


class _BestSoFar(optuna.samplers.RandomSampler):
    """Reads every finished trial's value, which a failed trial lacks."""

    def sample_independent(self, study, trial, name, distribution):
        sum(t.value + 0.0 for t in study.get_trials(deep_copy=False) if t.state.is_finished())
        return super().sample_independent(study, trial, name, distribution)


class _FirstRangeOnly(optuna.samplers.RandomSampler):
    """Samples each parameter from the first distribution it saw under that name."""

    def __init__(self, seed=None):
        super().__init__(seed=seed)
        self.seen = {}

    def sample_independent(self, study, trial, name, distribution):
        return super().sample_independent(study, trial, name, self.seen.setdefault(name, distribution))


@pytest.mark.parametrize("check,factory,message", [
    pytest.param(check_predictions_in_um, _Millimetres, "prediction RMS", id="model-in-mm"),
    pytest.param(check_model_deterministic, _Unseeded, "same seed differ", id="model-unseeded"),
    pytest.param(check_fit_predict_shape, _FirstChannelOnly, "shape", id="model-drops-a-channel"),
    pytest.param(check_constructor_only_stores_params, _ConvertsInInit, "changed parameter 'scale'",
                 id="model-converts-in-init"),
    pytest.param(check_clone, _ConvertsInInit, "clone", id="model-not-clonable"),
    pytest.param(check_search_space, _BadSearchSpace, "not constructor parameters", id="model-space-unknown-param"),
    pytest.param(check_streaming_equals_batch, _ClaimsNoMemory, "streaming one row", id="model-stream-differs"),
    pytest.param(check_search_space, _Diverging, "non-finite", id="model-space-point-diverges"),
    pytest.param(check_selection_deterministic, _RandomPick, "same seed selected", id="selector-unseeded"),
    pytest.param(check_selection_idempotent, _DropsLast, "refitting on the selected columns", id="selector-unstable"),
    pytest.param(check_seed_reproducible, lambda seed=None: optuna.samplers.RandomSampler(), "same seed, different",
                 id="optimizer-ignores-seed"),
    pytest.param(check_respects_search_space, lambda seed=None: _OffGrid(seed=seed), "is outside",
                 id="optimizer-leaves-bounds"),
    pytest.param(check_survives_failed_and_pruned_trials, lambda seed=None: _BestSoFar(seed=seed),
                 "broke after failed and pruned trials: TypeError", id="optimizer-breaks-on-a-failed-trial"),
    pytest.param(check_dynamic_search_space, lambda seed=None: _FirstRangeOnly(seed=seed), "is outside",
                 id="optimizer-keeps-an-old-range"),
    pytest.param(check_returns_recording, lambda: pd.DataFrame({"t": [1.0]}), "not a thermodrift Recording",
                 id="dataset-not-a-recording"),
])
def test_check_catches(check, factory, message):
    with pytest.raises(AssertionError, match=message):
        check(factory, {})


def test_a_sound_model_passes_and_the_report_lists_every_failure():
    check_model(_Linear)
    with pytest.raises(ConformanceError) as err:
        check_model(_Millimetres)
    report = str(err.value)
    assert f"failed 1 of {len(MODEL_CHECKS)} checks" in report and "check_predictions_in_um [params {}]" in report


def test_a_component_without_yaml_composes_from_its_registry_entry():
    reg = Registry()
    reg.add("model", "unconfigured_linear", _Linear)
    check_component("model", "unconfigured_linear", reg)  # check_hydra_config included
    cfg = compose_config(["model=unconfigured_linear", "model.params.scale=2.5"], reg.searchpaths, reg)
    assert cfg.model.name == "unconfigured_linear" and cfg.model.params.scale == 2.5
    assert cfg.model.search_space == {}


def test_check_component_includes_the_hydra_config():
    reg = Registry()
    reg.add("model", "mlr", _BadSearchSpace)  # its search space tunes units, which it lacks
    with pytest.raises(ConformanceError, match=r"check_hydra_config: .*not constructor parameters"):
        check_component("model", "mlr", reg)
