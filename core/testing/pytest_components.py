"""pytest test classes that a plugin's own test suite subclasses (like ``optuna.testing.pytest_samplers``).

Name the registered component (its entry point must be installed) or give the factory directly::

    from thermodrift.testing.pytest_components import ModelTests

    class TestRidgeDemo(ModelTests):
        name = "ridge_demo"          # looked up in the registry; also checks conf/model/ridge_demo.yaml

    class TestDraft(ModelTests):
        factory = MyDraftModel       # not registered yet: the contract only, no Hydra config

Each check of the kind runs once per parameter set of ``get_test_params()``, as
``test_contract[<check>-<set>]``.
"""

from __future__ import annotations

from typing import Any, Callable, ClassVar

import pytest

from thermodrift.core import registry
from thermodrift.testing.config_checks import check_hydra_config
from thermodrift.testing.suite import checks, parameter_sets


class ComponentTests:
    """Base of the per-kind classes; set ``name`` (registered) or ``factory`` in the subclass."""

    kind: ClassVar[str]
    name: ClassVar[str | None] = None
    factory: ClassVar[Callable[..., Any] | None] = None

    @classmethod
    def _factory(cls) -> Callable[..., Any]:
        if cls.factory is not None:
            return cls.factory
        if cls.name is None:
            raise TypeError(f"{cls.__name__}: set `name` (a registered {cls.kind}) or `factory`")
        return registry.get(cls.kind, cls.name).factory

    def pytest_generate_tests(self, metafunc: pytest.Metafunc) -> None:
        if metafunc.definition.originalname != "test_contract":
            return
        kind_checks = checks(self.kind)
        sets = parameter_sets(self._factory())
        metafunc.parametrize("check", kind_checks, ids=[c.__name__.removeprefix("check_") for c in kind_checks])
        metafunc.parametrize("params", sets, ids=[f"params{i}" for i in range(len(sets))])

    def test_contract(self, check: Callable[[Callable[..., Any], dict], None], params: dict) -> None:
        check(self._factory(), params)


class _ConfiguredTests(ComponentTests):
    """A kind with a Hydra config group (selector, model, optimizer, dataset): its config is checked too."""

    def test_hydra_config(self) -> None:
        if self.name is None:
            pytest.skip("only a registered component (set `name`) has a Hydra config")
        check_hydra_config(self.kind, self.name, registry.default())


class SelectorTests(_ConfiguredTests):
    """The selector contract: estimator params, clone, pickle, seeded and stable selection of input columns."""

    kind = "selector"


class ModelTests(_ConfiguredTests):
    """The model contract: estimator params, clone, pickle, seeded fits, (n, k) predictions in µm, search space."""

    kind = "model"


class OptimizerTests(_ConfiguredTests):
    """The optimizer contract: an Optuna sampler that keeps the budget and the space and repeats with a seed."""

    kind = "optimizer"


class DatasetTests(_ConfiguredTests):
    """The dataset contract: a deterministic Recording with temperatures and a target (displacement or temperature)."""

    kind = "dataset"


class MechanismTests(ComponentTests):
    """The mechanism contract: signature and drivers, free parameters at each place, neutral values change
    nothing, missing drivers named, a reason where it has no place."""

    kind = "mechanism"


class CncFormatTests(ComponentTests):
    """The controller-format contract: a header starting with ``time_s``, rows as long as it, deterministic, a
    temperature target refused by a format that writes displacements."""

    kind = "cnc"
