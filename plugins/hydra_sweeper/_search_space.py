"""Hydra override syntax -> Optuna distributions, and a trial's parameters -> the job's overrides.

    x: interval(-5.0, 5.0)                 FloatDistribution(-5.0, 5.0)
    lr: tag(log, interval(1e-4, 1e-1))     FloatDistribution(1e-4, 1e-1, log=True)
    units: int(interval(8, 64))            IntDistribution(8, 64)           both ends included
    units: tag(log, int(interval(8, 64)))  IntDistribution(8, 64, log=True)
    n: range(1, 10)                        IntDistribution(1, 9)            Hydra's range excludes stop
    w: range(0.0, 1.0, 0.25)               FloatDistribution(0.0, 0.75, step=0.25)
    act: choice(relu, tanh)  or  relu,tanh CategoricalDistribution(("relu", "tanh"))
    depth: 3                               not searched; passed to every job unchanged
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

from optuna.distributions import BaseDistribution, CategoricalDistribution, FloatDistribution, IntDistribution

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import IntervalSweep, Override, QuotedString, Transformer

_TAGS = {"log"}


@dataclass
class SearchSpace:
    """Distributions to sample, the overrides every job gets unchanged, and how to write sampled values."""

    distributions: dict[str, BaseDistribution] = field(default_factory=dict)
    fixed: list[str] = field(default_factory=list)
    # Override text of each categorical choice, index-aligned with the distribution's choices: the Optuna
    # choice is a plain value ("a b", or "[1,2]" for a list) while the job needs override syntax ('a b', [1,2]).
    choice_text: dict[str, list[str]] = field(default_factory=dict)

    def overrides(self, params: Mapping[str, Any]) -> list[str]:
        """The job's overrides for a trial's parameters (including any a custom search space suggested)."""
        out = list(self.fixed)
        for name, value in params.items():
            dist = self.distributions.get(name)
            if isinstance(dist, CategoricalDistribution):
                text = self.choice_text[name][int(dist.to_internal_repr(value))]
            else:
                text = Transformer.str(value)
            out.append(f"{name}={text}")
        return out

    def corner_overrides(self) -> list[list[str]]:
        """Job overrides that together take every choice and both ends of every numeric range once."""
        if not self.distributions:
            return [list(self.fixed)]
        width = max((len(d.choices) for d in self.distributions.values()
                     if isinstance(d, CategoricalDistribution)), default=2)
        return [self.overrides({name: d.choices[i % len(d.choices)] if isinstance(d, CategoricalDistribution)
                                else (d.low, d.high)[i % 2] for name, d in self.distributions.items()})
                for i in range(max(width, 2))]


def parse(params: Mapping[str, Any], arguments: Sequence[str], parser: OverridesParser) -> SearchSpace:
    """Build the search space from the sweeper's ``params`` and the command line (which wins on equal keys)."""
    lines = [f"{key}={_as_override_text(value)}" for key, value in params.items()]
    overrides: dict[str, Override] = {}
    for override in parser.parse_overrides([*lines, *arguments]):
        overrides[override.get_key_element()] = override
    space = SearchSpace()
    for name, override in overrides.items():
        if not override.is_sweep_override():
            space.fixed.append(override.input_line)
            continue
        try:
            log = _log_scale(override)
            if override.is_choice_sweep():
                if log:
                    raise ValueError("tag(log, ...) needs an interval, e.g. tag(log, interval(1e-4, 1e-1))")
                raw = list(override.sweep_iterator())  # one pass: shuffle(...) reorders on every iteration
                space.distributions[name] = CategoricalDistribution([_choice_value(v) for v in raw])
                space.choice_text[name] = [Transformer.str(v) for v in raw]
            else:
                space.distributions[name] = _numeric(override, log)
        except ValueError as exc:
            raise ValueError(f"search space {override.input_line!r}: {exc}") from None
    return space


def _log_scale(override: Override) -> bool:
    tags = set(getattr(override.value(), "tags", ()))  # glob(...) choices carry no tags
    if tags - _TAGS:
        raise ValueError(f"unknown tag(s) {sorted(tags - _TAGS)}; this sweeper reads only 'log'")
    return "log" in tags


def _numeric(override: Override, log: bool) -> FloatDistribution | IntDistribution:
    sweep = override.value()
    if override.is_interval_sweep():
        assert isinstance(sweep, IntervalSweep)
        if isinstance(sweep.start, int) and isinstance(sweep.end, int):
            return IntDistribution(sweep.start, sweep.end, log=log)
        return FloatDistribution(float(sweep.start), float(sweep.end), log=log)
    assert override.is_range_sweep()
    if log:
        raise ValueError("a range has a step, which a log scale cannot have; use tag(log, int(interval(a, b)))")
    values = list(override.sweep_iterator())
    if not values:
        raise ValueError("empty range")
    step = abs(sweep.step)
    if all(isinstance(v, int) for v in values):
        return IntDistribution(min(values), max(values), step=step)
    return FloatDistribution(min(values), max(values), step=float(step))


def _choice_value(value: Any) -> Any:
    if isinstance(value, QuotedString):
        return value.text
    return Transformer.encode(value)  # lists and dicts become their override text; Optuna stores primitives only


def _as_override_text(value: Any) -> str:
    # Strings in `params` are override syntax already; other YAML values (3, [1, 2], null) are written as such.
    return value if isinstance(value, str) else Transformer.str(value)
