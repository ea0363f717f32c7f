"""Inner validation that asks the outer question: is a pipeline good on a working condition it has not seen?

Inside the outer training part, forward chaining over its working conditions: fold k trains on every row before
the first row of condition k and validates on condition k's rows, for the last ``max_folds`` conditions (each
later condition predicted from the earlier ones). A training part with a single working condition is cut into
``n_blocks`` equal time blocks instead, chained the same way. Only outer training rows are used, and a fold's
model never sees a row of its future: its history is the unbroken run of training rows just before the
validation block (inputs only).

A training part of several runs (independent recordings, each a cold start) is validated by run instead: its
runs, in time order, are cut into ``max_folds`` contiguous groups, and fold k validates group k with a model
fitted on every other training run, so every training run is validated once, not only the last ones.

:func:`aggregate` turns per-fold RMSEs into one score in which a pipeline good on every fold beats one best on
one fold: the mean of the fold RMSEs plus their worst, halved.
"""

from __future__ import annotations

import numpy as np

from thermodrift.core import splits
from thermodrift.core.errors import InputError

MIN_SHARE = 0.05  # a condition with fewer of the training rows is merged into its neighbour's fold


def inner_folds(recording, train: np.ndarray, max_folds: int = 3, n_blocks: int = 4) -> list[splits.Fold]:
    """Forward-chaining folds (row positions into ``recording``) inside the outer training rows ``train``."""
    train = np.asarray(train)
    runs = recording.runs().to_numpy()[train]
    order = list(dict.fromkeys(runs))
    if len(order) >= 2:
        groups = [g for g in np.array_split(np.asarray(order, dtype=object), min(max_folds, len(order))) if len(g)]
        folds = []
        for group in groups:
            held = np.isin(runs, group)
            if np.count_nonzero(~held) >= 2:
                folds.append(splits.Fold(train[~held], train[held], f"inner: run {', '.join(group)} from the "
                                         "other training runs"))
        if folds:
            return folds
    labels = recording.conditions().to_numpy()[train]
    order = [c for c in dict.fromkeys(labels) if np.count_nonzero(labels == c) >= MIN_SHARE * len(labels)]
    folds = []
    if len(order) >= 2:
        for cond in order[1:]:
            rows = np.flatnonzero(labels == cond)
            first = rows[0]
            fit = np.arange(first)
            if len(fit) >= 2:
                folds.append(splits.Fold(train[fit], train[rows], f"inner: {cond} from the conditions before"))
    if not folds:
        edges = np.linspace(0, len(train), n_blocks + 1).round().astype(int)
        for k in range(1, n_blocks):
            if edges[k] >= 2 and edges[k + 1] > edges[k]:
                folds.append(splits.Fold(train[:edges[k]], train[edges[k]:edges[k + 1]],
                                         f"inner: time block {k + 1} of {n_blocks} from the blocks before"))
    if not folds:
        raise InputError(f"{recording.source}: the training part ({len(train)} rows) is too short for inner "
                         "validation", hint="hold out less, or record longer")
    return folds[-max_folds:]


def aggregate(fold_rmse: list[float] | np.ndarray) -> float:
    """One score from per-fold RMSEs (µm): (mean + worst) / 2; infinite when a fold is not finite."""
    r = np.asarray(fold_rmse, dtype=float)
    if not len(r) or not np.isfinite(r).all():
        return float("inf")
    return float(0.5 * (r.mean() + r.max()))
