"""Run every contract check of a component kind and report all failures at once."""

from __future__ import annotations

from typing import Any, Callable

from thermodrift.core import registry as registry_module
from thermodrift.core.registry import CONFIG_GROUPS, Registry
from thermodrift.testing.cnc_checks import CNC_CHECKS
from thermodrift.testing.config_checks import check_hydra_config
from thermodrift.testing.dataset_checks import DATASET_CHECKS
from thermodrift.testing.mechanism_checks import MECHANISM_CHECKS
from thermodrift.testing.model_checks import MODEL_CHECKS
from thermodrift.testing.optimizer_checks import OPTIMIZER_CHECKS
from thermodrift.testing.selector_checks import SELECTOR_CHECKS

Check = Callable[[Callable[..., Any], dict], None]
CHECKS: dict[str, tuple[Check, ...]] = {
    "selector": SELECTOR_CHECKS,
    "model": MODEL_CHECKS,
    "optimizer": OPTIMIZER_CHECKS,
    "dataset": DATASET_CHECKS,
    "mechanism": MECHANISM_CHECKS,
    "cnc": CNC_CHECKS,
}


class ConformanceError(AssertionError):
    """A component broke its contract; the message lists every failed check with its parameters."""


def checks(kind: str) -> tuple[Check, ...]:
    """The contract checks for ``kind`` (each ``check(factory, params)`` raises ``AssertionError``)."""
    if kind not in CHECKS:
        raise ValueError(f"no conformance checks for kind {kind!r}; kinds with checks: {', '.join(CHECKS)}")
    return CHECKS[kind]


def parameter_sets(factory: Callable[..., Any]) -> list[dict]:
    """The factory's cheap parameter sets (``get_test_params()``), ``[{}]`` if it has none."""
    getter = getattr(factory, "get_test_params", None)
    sets = list(getter()) if callable(getter) else [{}]
    if not sets or not all(isinstance(p, dict) for p in sets):
        raise ConformanceError(f"get_test_params() must return a non-empty list of dicts, got {sets!r}")
    return sets


def _failures(kind: str, factory: Callable[..., Any]) -> tuple[int, list[str]]:
    run, failed = 0, []
    for params in parameter_sets(factory):
        for check in checks(kind):
            run += 1
            try:
                check(factory, params)
            except Exception as exc:  # report every broken contract, not only the first
                failed.append(f"{check.__name__} [params {params}]: {_describe(exc)}")
    return run, failed


def _describe(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return text if isinstance(exc, AssertionError) and text else f"raised {type(exc).__name__}: {text}"


def _raise(what: str, run: int, failed: list[str]) -> None:
    if failed:
        raise ConformanceError(f"{what} failed {len(failed)} of {run} checks:\n  " + "\n  ".join(failed))


def check_factory(kind: str, factory: Callable[..., Any]) -> None:
    """Run every ``kind`` check on ``factory`` with each of its test parameter sets; raise listing all failures."""
    run, failed = _failures(kind, factory)
    _raise(f"{kind} {getattr(factory, '__qualname__', factory)!r}", run, failed)


def check_selector(cls: type) -> None:
    """Run the selector contract on ``cls`` (a ``Selector`` subclass)."""
    check_factory("selector", cls)


def check_model(cls: type) -> None:
    """Run the model contract on ``cls`` (a ``ThermalModel`` subclass)."""
    check_factory("model", cls)


def check_optimizer(factory: Callable[..., Any]) -> None:
    """Run the optimizer contract on ``factory`` (``factory(seed=..., **params)`` returns an Optuna sampler)."""
    check_factory("optimizer", factory)


def check_dataset(factory: Callable[..., Any]) -> None:
    """Run the dataset contract on ``factory`` (``factory(**params)`` returns a Recording)."""
    check_factory("dataset", factory)


def check_mechanism(cls: type) -> None:
    """Run the mechanism contract on ``cls`` (a ``Mechanism`` subclass)."""
    check_factory("mechanism", cls)


def check_cnc_format(cls: type) -> None:
    """Run the controller-format contract on ``cls`` (a ``thermodrift.compensator.cnc.Format`` subclass)."""
    check_factory("cnc", cls)


def check_component(kind: str, name: str, registry: Registry | None = None) -> None:
    """Run every check on the registered component ``name`` of ``kind``, including its Hydra config.

    ``registry`` defaults to the process-wide one (every installed plugin).
    """
    reg = registry or registry_module.default()
    component = reg.get(kind, name)
    run, failed = _failures(kind, component.factory)
    if kind in CONFIG_GROUPS:
        run += 1
        try:
            check_hydra_config(kind, name, reg)
        except Exception as exc:
            failed.append(f"check_hydra_config: {_describe(exc)}")
    _raise(f"{kind} {name!r} from {component.origin}", run, failed)
