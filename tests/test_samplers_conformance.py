"""Optuna's own sampler conformance suite (``optuna.testing.pytest_samplers``) on every population sampler,
built through the registry exactly as a study builds it, and on the one-file metaheuristic template
(docs/templates/optimizer_plugin.py) loaded as a plugin author's module."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import optuna
import pytest
import yaml
from optuna.testing.pytest_samplers import BasicSamplerTestCase, RelativeSamplerTestCase, SingleOnlySamplerTestCase

from thermodrift.core import configs, registry
from thermodrift.testing.suite import parameter_sets

from support import load_file

OURS = ["pso", "pso_constriction", "gwo", "fa", "rbmo", "rbmox", "sho"]
REGISTRY = registry.load()
CONF = Path(__file__).resolve().parents[1] / "conf" / "optimizer"
TEMPLATE = Path(__file__).resolve().parents[1] / "docs" / "templates" / "optimizer_plugin.py"


def _template_registry() -> registry.Registry:
    """A registry holding only the template's optimizer, registered by its own hook."""
    # the suite pickles samplers, which imports the class by module name
    module = load_file(TEMPLATE, "template_optimizer_plugin", sys.modules.__setitem__)
    reg = registry.Registry()
    module.thermodrift_register_optimizers(registry=reg)
    return reg


TEMPLATE_REGISTRY = _template_registry()


def test_all_population_samplers_are_registered():
    assert set(OURS) <= set(REGISTRY.names("optimizer"))
    for name in OURS:
        sampler = REGISTRY.create("optimizer", name, seed=0)  # defaults for everything but the seed
        assert sampler.population_size >= 2 and sampler.n_trials == 100


# Each sampler with each of its cheap parameter sets (population sizes of 3-12: the suite's studies have
# 1-20 trials, so small populations exercise several generations and slot re-proposals).
CASES = [(name, i) for name in OURS for i in range(len(parameter_sets(REGISTRY.get("optimizer", name).factory)))]


class TestPopulationSamplers(BasicSamplerTestCase, RelativeSamplerTestCase, SingleOnlySamplerTestCase):
    @pytest.fixture(params=CASES, ids=[f"{name}-{i}" for name, i in CASES])
    def sampler(self, request):
        name, i = request.param
        component = REGISTRY.get("optimizer", name)
        params = parameter_sets(component.factory)[i]
        return lambda: component.factory(seed=0, **params)


class TestTemplateSampler(BasicSamplerTestCase, RelativeSamplerTestCase, SingleOnlySamplerTestCase):
    @pytest.fixture(params=[0, 1], ids=["jaya-0", "jaya-1"])
    def sampler(self, request):
        (name,) = TEMPLATE_REGISTRY.names("optimizer")
        factory = TEMPLATE_REGISTRY.get("optimizer", name).factory
        params = parameter_sets(factory)[request.param]
        return lambda: factory(seed=0, **params)


@pytest.mark.parametrize("config", ["pso", "pso_constriction", "pso_s1", "pso_s2", "pso_s3", "gwo", "fa", "rbmo",
                                    "rbmox", "sho"])
def test_optimizer_configs_build_their_sampler(config):
    shipped = CONF / f"{config}.yaml"  # a preset; without one, the config generated from the factory
    spec = yaml.safe_load(shipped.read_text()) if shipped.exists() else configs.node(REGISTRY.get("optimizer", config))
    sampler = REGISTRY.create("optimizer", spec["name"], seed=0, n_trials=50, **spec["params"])
    given = {k: v for k, v in spec["params"].items() if v is not None}  # None: derived from the budget
    assert {k: getattr(sampler, k) for k in given} == given


OPTUNA_OWN = {"random": lambda seed: optuna.samplers.RandomSampler(seed=seed),
              "tpe": lambda seed: optuna.samplers.TPESampler(seed=seed, n_startup_trials=10, multivariate=True),
              "cmaes": lambda seed: optuna.samplers.CmaEsSampler(seed=seed, n_startup_trials=1,
                                                                 warn_independent_sampling=False),
              "gp": lambda seed: optuna.samplers.GPSampler(seed=seed, n_startup_trials=10)}


def _workers(samplers, rounds: int) -> list[tuple]:
    """Workers sharing one study, each with its own sampler object, taking turns; every trial's parameters."""
    storage = optuna.storages.InMemoryStorage()
    studies = [optuna.create_study(storage=storage, study_name="shared", sampler=s, load_if_exists=True)
               for s in samplers]
    for _ in range(rounds):
        for study in studies:
            trial = study.ask()
            x, y = trial.suggest_float("x", -5, 5), trial.suggest_float("y", 1e-3, 1e3, log=True)
            study.tell(trial, (x - 1) ** 2 + abs(y - 3))
    return [tuple(sorted(t.params.items())) for t in studies[0].trials]


@pytest.mark.parametrize("name", sorted(OPTUNA_OWN))
def test_optunas_samplers_give_each_worker_its_own_stream(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        # three workers built with the same seed (as every worker of a study is) repeat none of their draws
        shared = _workers([registry.create_sampler(name, seed=7, n_trials=12) for _ in range(3)], rounds=4)
        assert len(set(shared)) == len(shared) == 12
        # a lone worker draws exactly Optuna's own sequence for that seed
        alone = _workers([registry.create_sampler(name, seed=7, n_trials=12)], rounds=12)
        assert alone == _workers([OPTUNA_OWN[name](7)], rounds=12)
        if name == "random":  # draws that do not depend on the history: the first worker's are the lone one's
            assert shared[::3] == alone[:4]
