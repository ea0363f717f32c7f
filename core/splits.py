"""Train/test splits of a recording. The defaults are honest: time order and working conditions are respected.

Neighbouring samples 15–60 s apart are almost identical, so a shuffled split lets a model interpolate in time
(on FL_THERMAL a random forest scores R² 1.000 shuffled and −1.02 with the 5000 rpm block held out).
:class:`Shuffled` exists only to reproduce a paper's protocol; it is labelled and warns.

Every split returns :class:`Fold` objects holding row positions. ``inner_fold`` gives the validation fold that
a study tunes on, taken inside a training part the same honest way.
"""

from __future__ import annotations

import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from thermodrift.core import registry
from thermodrift.core.errors import InputError


@dataclass(frozen=True)
class Fold:
    """Row positions of one train/test pair; ``name`` says what is held out."""

    train: np.ndarray
    test: np.ndarray
    name: str


class Split(ABC):
    """A way to cut a recording into folds. ``protocol`` is "honest" or "paper" (leaky, for reproduction)."""

    protocol = "honest"

    @abstractmethod
    def folds(self, recording) -> list[Fold]:
        """The folds of ``recording`` (row positions into it)."""

    def describe(self) -> str:
        return type(self).__name__


def inner_fold(recording, fraction: float = 0.25, min_share: float = 0.05) -> Fold:
    """Validation fold inside a training part: hold out its last working condition when it has two or more,
    else its last ``fraction`` of time. Conditions with under ``min_share`` of the rows at the end (the first
    samples of a held-out block that a time cut left in the training part) are left out of both sides."""
    labels = recording.conditions().to_numpy()
    order = list(dict.fromkeys(labels))
    while order and np.count_nonzero(labels == order[-1]) < min_share * len(labels):
        order.pop()
    if len(order) >= 2:
        val = labels == order[-1]
        train = np.flatnonzero(np.isin(labels, order[:-1]))
        return _fold(train[train < np.flatnonzero(val)[0]], np.flatnonzero(val),
                     f"inner: condition {order[-1]} held out")
    return Chronological(test_fraction=fraction).folds(recording)[0]


class Chronological(Split):
    """Train on the first part of the recording, test on the last ``test_fraction`` of its time, or on its last
    ``test_last_h`` hours when given (e.g. 336: the last two weeks), after an optional gap in s."""

    def __init__(self, test_fraction: float = 0.3, gap_s: float = 0.0, test_last_h: float | None = None):
        if not 0 < test_fraction < 1:
            raise InputError(f"split.test_fraction must be in (0, 1), got {test_fraction}")
        if test_last_h is not None and not test_last_h > 0:
            raise InputError(f"split.test_last_h must be positive or null, got {test_last_h!r}")
        self.test_fraction, self.gap_s, self.test_last_h = test_fraction, gap_s, test_last_h

    def folds(self, recording) -> list[Fold]:
        t = recording.time_s
        if self.test_last_h is None:
            cut, name = t[0] + (1 - self.test_fraction) * (t[-1] - t[0]), f"last {self.test_fraction:.0%} of time"
        else:  # the last test_last_h hours, the final sample's interval included
            step = recording.sampling_interval_s if len(t) > 1 else 0.0
            cut, name = t[-1] + step - 3600.0 * self.test_last_h, f"last {self.test_last_h:g} h"
            if cut <= t[0]:
                raise InputError(f"{recording.source}: split.test_last_h={self.test_last_h:g} holds out the whole "
                                 f"recording ({(t[-1] - t[0]) / 3600:.1f} h)", hint="hold out fewer hours")
        train = np.flatnonzero(t < cut - self.gap_s)
        test = np.flatnonzero(t >= cut)
        return [_fold(train, test, name)]


class ConditionHoldout(Split):
    """Hold out whole working conditions (speed blocks with their cool-downs, or a ``condition`` channel).

    ``test_conditions``: labels, or substrings such as ``"5000rpm"`` matched against labels; default the last
    condition. ``train_on``: ``"before"`` (only conditions that precede the held-out ones, as a deployed model
    would see them) or ``"others"`` (every other condition). ``train_end_h``: training rows only before this
    time (hours from the start), e.g. the other conditions of a recording's first 40 h.
    """

    def __init__(self, test_conditions: list[str] | None = None, train_on: str = "before",
                 train_end_h: float | None = None):
        if train_on not in ("before", "others"):
            raise InputError(f"split.train_on must be 'before' or 'others', got {train_on!r}")
        if train_end_h is not None and not train_end_h > 0:
            raise InputError(f"split.train_end_h must be positive or null, got {train_end_h!r}")
        self.test_conditions = list(test_conditions) if test_conditions else None
        self.train_on, self.train_end_h = train_on, train_end_h

    def folds(self, recording) -> list[Fold]:
        labels = recording.conditions().to_numpy()
        order = list(dict.fromkeys(labels))
        if len(order) < 2:
            raise InputError(f"{recording.source}: only one working condition ({order[0]!r}) was found, so none "
                             "can be held out", hint="use split=chronological or add a 'condition' channel")
        wanted = self.test_conditions or [order[-1]]
        held = [lab for lab in order if any(w == lab or str(w) in lab for w in wanted)]
        if not held:
            raise InputError(f"split.test_conditions {wanted} match none of the conditions {order}")
        test_mask = np.isin(labels, held)
        if self.train_on == "before":
            first = np.flatnonzero(test_mask)[0]
            train_mask = np.zeros_like(test_mask)
            train_mask[:first] = True
        else:
            train_mask = ~test_mask
        name = f"held out: {', '.join(held)}"
        if self.train_end_h is not None:
            train_mask &= (recording.time_s - recording.time_s[0]) / 3600.0 < self.train_end_h
            name += f"; trained on t < {self.train_end_h:g} h"
        if not train_mask.any():
            raise InputError(f"{recording.source}: no training rows are left before the held-out conditions {held}"
                             + (f" and t < {self.train_end_h:g} h" if self.train_end_h is not None else ""),
                             hint="hold out a later condition, use train_on=others, or raise split.train_end_h")
        return [_fold(np.flatnonzero(train_mask), np.flatnonzero(test_mask), name)]


class TimeWindow(Split):
    """Train on ``t < train_end_h``, test on ``test_start_h ≤ t < test_end_h`` (hours from the start).

    The project's reference protocol "FL_THERMAL 5000 rpm held out" is train_end_h = test_start_h = 24.13,
    test_end_h = 32.13.
    """

    def __init__(self, train_end_h: float, test_start_h: float, test_end_h: float | None = None):
        self.train_end_h, self.test_start_h, self.test_end_h = train_end_h, test_start_h, test_end_h

    def folds(self, recording) -> list[Fold]:
        h = (recording.time_s - recording.time_s[0]) / 3600.0
        end = np.inf if self.test_end_h is None else self.test_end_h
        return [_fold(np.flatnonzero(h < self.train_end_h),
                      np.flatnonzero((h >= self.test_start_h) & (h < end)),
                      f"train t < {self.train_end_h} h, test {self.test_start_h}–{end} h")]


class ForwardChaining(Split):
    """Expanding-window folds over working conditions: train on conditions 1..k, test on condition k+1."""

    def __init__(self, min_train_conditions: int = 2):
        self.min_train_conditions = min_train_conditions

    def folds(self, recording) -> list[Fold]:
        labels = recording.conditions().to_numpy()
        order = list(dict.fromkeys(labels))
        if len(order) <= self.min_train_conditions:
            raise InputError(f"{recording.source}: forward chaining needs more than {self.min_train_conditions} "
                             f"working conditions, found {len(order)}", hint="use split=chronological")
        out = []
        for k in range(self.min_train_conditions, len(order)):
            test = labels == order[k]
            first = np.flatnonzero(test)[0]
            out.append(_fold(np.arange(first), np.flatnonzero(test), f"fold {k}: {order[k]} held out"))
        return out


class RunHoldout(Split):
    """Hold out whole runs (independent recordings: files, sheets or blocks of a ``run`` column).

    ``test_runs``: run names, or substrings matched against them; default the last run. ``train_on``:
    ``"others"`` (every other run: runs are independent, each a cold start) or ``"before"`` (only runs that
    precede the first held-out one in time).
    """

    def __init__(self, test_runs: list[str] | None = None, train_on: str = "others"):
        if train_on not in ("before", "others"):
            raise InputError(f"split.train_on must be 'before' or 'others', got {train_on!r}")
        self.test_runs = list(test_runs) if test_runs else None
        self.train_on = train_on

    def folds(self, recording) -> list[Fold]:
        runs, order = _runs(recording, 2, "split=chronological")
        wanted = self.test_runs or [order[-1]]
        held = [r for r in order if any(str(w) == r for w in wanted)] or \
            [r for r in order if any(str(w) in r for w in wanted)]
        if not held:
            raise InputError(f"split.test_runs {wanted} match none of the runs {order}")
        test = np.isin(runs, held)
        train = ~test if self.train_on == "others" else np.arange(len(runs)) < np.flatnonzero(test)[0]
        return [_fold(np.flatnonzero(train), np.flatnonzero(test), f"held out: run {', '.join(held)}")]


class LeaveOneRunOut(Split):
    """One fold per run: train on every other run, test on it (runs are independent cold starts)."""

    def folds(self, recording) -> list[Fold]:
        runs, order = _runs(recording, 2, "split=chronological")
        return [_fold(np.flatnonzero(runs != r), np.flatnonzero(runs == r), f"run {r} left out") for r in order]


class RunForwardChaining(Split):
    """Expanding-window folds over runs in time order: train on runs 1..k, test on run k+1."""

    def __init__(self, min_train_runs: int = 1):
        self.min_train_runs = min_train_runs

    def folds(self, recording) -> list[Fold]:
        runs, order = _runs(recording, self.min_train_runs + 1, "split=chronological")
        return [_fold(np.flatnonzero(np.isin(runs, order[:k])), np.flatnonzero(runs == order[k]),
                      f"fold {k}: run {order[k]} from the runs before") for k in range(self.min_train_runs, len(order))]


def _runs(recording, at_least: int, instead: str) -> tuple[np.ndarray, list[str]]:
    runs = recording.runs().to_numpy()
    order = list(dict.fromkeys(runs))
    if len(order) < at_least:
        raise InputError(f"{recording.source}: this split needs at least {at_least} runs, found {len(order)}",
                         hint=f"load several tables (or a 'run:' column) as runs, or use {instead}")
    return runs, order


class Shuffled(Split):
    """PAPER PROTOCOL (leaky): a random row split, only to reproduce published numbers. Warns when used."""

    protocol = "paper"

    def __init__(self, test_fraction: float = 0.2, seed: int = 0):
        self.test_fraction, self.seed = test_fraction, seed

    def folds(self, recording) -> list[Fold]:
        warnings.warn("split=shuffled is a paper protocol: neighbouring samples leak between train and test, "
                      "so its scores overstate real accuracy; report it beside an honest split", stacklevel=2)
        n = len(recording.time_s)
        perm = np.random.default_rng(self.seed).permutation(n)
        n_test = max(1, int(round(self.test_fraction * n)))
        return [_fold(np.sort(perm[n_test:]), np.sort(perm[:n_test]), "paper protocol: shuffled rows")]


class PaperSession(Split):
    """PAPER PROTOCOL: a published study's cut of one session (working condition) into consecutive blocks.

    From the first row of the session ``condition`` (a label or substring; None: the first session), the first
    ``train`` units train, then each entry of ``test`` is one held-out block (one fold each, all on the same
    training block), in ``unit`` "samples" or "s". S1: 420 samples, train 360 / test 60 (or 336 / 84, the 80/20
    variant). S2: train 14,000 s / predict 2,000 s, and the generalisation protocol train 12,000 s, predict 2,000 s,
    then verify on 2,000 s never seen (``test=[2000, 2000]``). Chronological within one session, so it leaks no
    rows, but it tests only the session the model was trained on: runs are labelled ``protocol=paper``.
    """

    protocol = "paper"

    def __init__(self, train: float, test: float | list[float], unit: str = "samples",
                 condition: str | None = None, names: list[str] | None = None):
        if unit not in ("samples", "s"):
            raise InputError(f"split.unit must be 'samples' or 's', got {unit!r}")
        self.train, self.unit, self.condition = train, unit, condition
        self.test = [float(t) for t in (test if isinstance(test, (list, tuple)) else [test])]
        self.names = list(names) if names else None
        if self.train <= 0 or not self.test or min(self.test) <= 0:
            raise InputError("split.train and every split.test block must be positive")
        if self.names is not None and len(self.names) != len(self.test):
            raise InputError(f"split.names needs one name per test block ({len(self.test)})")

    def folds(self, recording) -> list[Fold]:
        labels = recording.conditions().to_numpy()
        order = list(dict.fromkeys(labels))
        wanted = self.condition or order[0]
        match = [lab for lab in order if wanted == lab or str(wanted) in lab]
        if not match:
            raise InputError(f"split.condition {wanted!r} matches none of the conditions {order}")
        start = int(np.flatnonzero(labels == match[0])[0])
        if self.unit == "samples":
            pos = np.arange(len(labels)) - start
        else:
            t = recording.time_s
            pos = t - t[start]
        bounds = np.cumsum([self.train, *self.test])
        train = np.flatnonzero((pos >= 0) & (pos < bounds[0]))
        out = []
        for k, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
            name = (self.names[k] if self.names else f"block {k + 1}") + \
                f" ({match[0]}: train first {self.train:g} {self.unit}, test {lo:g}-{hi:g} {self.unit})"
            test = np.flatnonzero((pos >= lo) & (pos < hi))
            if len(test) < max(1, round(0.9 * (hi - lo) / (1 if self.unit == "samples" else
                                                        recording.sampling_interval_s))):
                raise InputError(f"split {name}: the recording has only {len(test)} rows there",
                                 hint="choose a longer recording or shorter blocks")
            out.append(_fold(train, test, f"paper protocol: {name}"))
        return out


SPLITS = {"chronological": Chronological, "condition_holdout": ConditionHoldout, "time_window": TimeWindow,
          "forward_chaining": ForwardChaining, "shuffled": Shuffled, "paper_session": PaperSession,
          "run_holdout": RunHoldout, "leave_one_run_out": LeaveOneRunOut, "run_forward_chaining": RunForwardChaining}


def make_split(kind: str, seed: int | None = None, **params) -> Split:
    """Build a split by its config name; ``seed`` reaches the splits that draw at random (unless ``params`` set it)."""
    if kind not in SPLITS:
        raise InputError(f"unknown split {kind!r}; use one of {', '.join(SPLITS)}")
    if seed is not None:
        params = registry.with_seed(SPLITS[kind], params, seed)
    return SPLITS[kind](**params)


def _fold(train: np.ndarray, test: np.ndarray, name: str) -> Fold:
    if len(train) < 2 or len(test) < 1:
        raise InputError(f"split '{name}' leaves {len(train)} training and {len(test)} test rows",
                         hint="choose other split parameters")
    return Fold(np.asarray(train), np.asarray(test), name)
