"""Optuna's own sampler conformance suite (``optuna.testing.pytest_samplers``) on every population sampler,
built through the registry exactly as a study builds it, and on the one-file metaheuristic template
(docs/templates/optimizer_plugin.py) loaded as a plugin author's module."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
import yaml
from optuna.testing.pytest_samplers import BasicSamplerTestCase, RelativeSamplerTestCase, SingleOnlySamplerTestCase

from thermodrift.core import configs, registry
from thermodrift.testing.suite import parameter_sets

OURS = ["pso", "pso_constriction", "gwo", "fa", "rbmo", "rbmox", "sho"]
REGISTRY = registry.load()
CONF = Path(__file__).resolve().parents[1] / "conf" / "optimizer"
TEMPLATE = Path(__file__).resolve().parents[1] / "docs" / "templates" / "optimizer_plugin.py"


def _template_registry() -> registry.Registry:
    """A registry holding only the template's optimizer, registered by its own hook."""
    spec = importlib.util.spec_from_file_location("template_optimizer_plugin", TEMPLATE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # the suite pickles samplers, which imports the class by module name
    spec.loader.exec_module(module)
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
