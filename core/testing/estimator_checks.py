"""Checks shared by selectors and models: the scikit-learn estimator contract.

Every check takes ``(factory, params)``, builds ``factory(**params)`` itself and raises ``AssertionError``
with a message that says what to fix.
"""

from __future__ import annotations

import inspect
import pickle
from typing import Any, Callable

import numpy as np
from sklearn.base import clone

from thermodrift.core.registry import with_seed

Factory = Callable[..., Any]


def same(a: Any, b: Any) -> bool:
    """Parameter equality that also holds for arrays, NaN and nested containers."""
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    if isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b):
        return True
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return False


def fitted_attributes(est: Any) -> list[str]:
    """Public attributes ending in ``_`` (scikit-learn's mark of a fitted attribute)."""
    return sorted(k for k in vars(est) if k.endswith("_") and not k.startswith("_"))


def check_constructor_only_stores_params(factory: Factory, params: dict) -> None:
    """``__init__`` stores each parameter unchanged under its own name and learns nothing."""
    est = factory(**params)
    got = est.get_params(deep=False)
    defaults = {name: p.default for name, p in inspect.signature(type(est).__init__).parameters.items()
                if p.default is not p.empty}
    for key, value in {**defaults, **params}.items():
        assert key in got, f"get_params() lacks constructor parameter {key!r}"
        assert same(getattr(est, key), value), (
            f"__init__ changed parameter {key!r} from {value!r} to {getattr(est, key)!r}; store it unchanged "
            "and validate or convert it in fit()")
    assert not fitted_attributes(est), f"__init__ set fitted attributes {fitted_attributes(est)}; set them in fit()"


def check_params_round_trip(factory: Factory, params: dict) -> None:
    """``get_params`` → constructor and ``set_params`` reproduce the same parameters."""
    est = factory(**params)
    got = est.get_params(deep=False)
    rebuilt = type(est)(**got).get_params(deep=False)
    changed = [k for k in got if not same(got[k], rebuilt.get(k))]
    assert not changed, f"type(est)(**est.get_params()) changes parameters {changed}"
    assert est.set_params(**got) is est, "set_params() must return self"
    again = est.get_params(deep=False)
    changed = [k for k in got if not same(got[k], again.get(k))]
    assert not changed, f"set_params(**get_params()) changes parameters {changed}"


def check_clone(factory: Factory, params: dict) -> None:
    """``sklearn.base.clone`` gives an unfitted copy with equal parameters."""
    est = factory(**params)
    try:
        copy = clone(est)
    except RuntimeError as exc:  # clone's own check that __init__ stores params unchanged
        raise AssertionError(f"sklearn.base.clone failed: {exc}") from None
    assert copy is not est and type(copy) is type(est), "clone must return a new object of the same class"
    orig, cloned = est.get_params(deep=False), copy.get_params(deep=False)
    changed = [k for k in orig if not same(orig[k], cloned.get(k))]
    assert not changed, f"clone changed parameters {changed}"


def pickled(obj: Any) -> Any:
    """``obj`` after a pickle round trip."""
    return pickle.loads(pickle.dumps(obj))


def seeded(est: Any, seed: int = 0) -> Any:
    """``est`` with ``seed`` under the name it takes one by (``random_state`` or ``seed``), if that is unset."""
    unset = {k for k, v in est.get_params(deep=False).items() if v is None}
    est.set_params(**{k: v for k, v in with_seed(type(est), {}, seed).items() if k in unset})
    return est


AUTOML_COSTS = ("cheap", "medium", "expensive", "skip")


def check_automl_metadata(factory: Factory, params: dict) -> None:
    """What AutoML and deployment read from the component, where it declares it: ``automl_cost`` one of cheap,
    medium, expensive, skip; ``automl_features`` a bool; ``automl_space`` a search space; ``refits_cheaply`` a bool
    (or a property of the instance, as a pipeline asks the model inside it)."""
    cost = getattr(factory, "automl_cost", None)
    assert cost is None or cost in AUTOML_COSTS, f"automl_cost {cost!r} is not one of {', '.join(AUTOML_COSTS)}"
    takes = getattr(factory, "automl_features", None)
    assert takes is None or isinstance(takes, bool), f"automl_features must be True or False, got {takes!r}"
    cheap = inspect.getattr_static(factory, "refits_cheaply", False)
    assert isinstance(cheap, (bool, property)), f"refits_cheaply must be True or False, got {cheap!r}"
    space = getattr(factory, "automl_space", None)
    if space is not None:
        from thermodrift.core.search_space import distributions

        distributions(dict(space))


SHARED_CHECKS = (check_constructor_only_stores_params, check_params_round_trip, check_clone, check_automl_metadata)
