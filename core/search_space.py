"""Search spaces as plain dicts (YAML-friendly) and their Optuna distributions.

Format: ``{param: {"type": "float", "low": 1e-4, "high": 1e-1, "log": true}}``; types ``float`` (optional
``log``, ``step``), ``int`` (optional ``log``, ``step``) and ``categorical`` (``choices``).
"""

from __future__ import annotations

from typing import Any, Mapping

import optuna
from optuna.distributions import BaseDistribution, CategoricalDistribution, FloatDistribution, IntDistribution

from thermodrift.core.errors import InputError


def distributions(space: Mapping[str, Mapping[str, Any]]) -> dict[str, BaseDistribution]:
    """Optuna distributions for a search-space dict; a malformed entry is an InputError naming it."""
    out: dict[str, BaseDistribution] = {}
    for name, spec in (space or {}).items():
        spec = dict(spec)
        kind = spec.pop("type", None)
        try:
            if kind == "float":
                out[name] = FloatDistribution(float(spec["low"]), float(spec["high"]), log=bool(spec.get("log", False)),
                                              step=None if spec.get("step") is None else float(spec["step"]))
            elif kind == "int":
                out[name] = IntDistribution(int(spec["low"]), int(spec["high"]), log=bool(spec.get("log", False)),
                                            step=int(spec.get("step", 1)))
            elif kind == "categorical":
                out[name] = CategoricalDistribution(list(spec["choices"]))
            else:
                raise ValueError(f"type must be float, int or categorical, got {kind!r}")
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"search_space.{name}: {exc}", hint="see the search-space format in the README") from None
    return out


def suggest(trial: optuna.Trial, space: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """Ask ``trial`` for every parameter of ``space``."""
    params: dict[str, Any] = {}
    for name, dist in distributions(space).items():
        if isinstance(dist, FloatDistribution):
            params[name] = trial.suggest_float(name, dist.low, dist.high, log=dist.log, step=dist.step)
        elif isinstance(dist, IntDistribution):
            params[name] = trial.suggest_int(name, dist.low, dist.high, log=dist.log, step=dist.step)
        else:
            params[name] = trial.suggest_categorical(name, dist.choices)
    return params
