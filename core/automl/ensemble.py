"""Greedy ensemble selection (Caruana et al., ICML 2004) over the inner-fold predictions of the top candidates.

With replacement: each step adds the member (possibly again) whose inclusion gives the best aggregated inner
score of the averaged predictions; the weights are the counts. Written here because the selection runs on our own
fold predictions and score (scikit-learn has no such selector); it is a few lines.
"""

from __future__ import annotations

from typing import Callable

import numpy as np


def caruana(preds: list[list[np.ndarray]], score: Callable[[list[np.ndarray]], float],
            steps: int = 25) -> tuple[np.ndarray, float]:
    """Weights (summing to 1) over ``preds`` (per candidate: its per-fold predictions) and the ensemble's score;
    stops early when no addition improves the score. Ties go to the earlier (better-ranked) candidate."""
    n = len(preds)
    counts = np.zeros(n)
    current: list[np.ndarray] | None = None
    best_score = float("inf")
    for _ in range(steps):
        size = counts.sum()
        trial_scores = []
        for i in range(n):
            mix = [p.copy() if current is None else (c * size + p) / (size + 1) for c, p in
                   zip(current or [None] * len(preds[i]), preds[i])]
            trial_scores.append(score(mix))
        i = int(np.argmin(trial_scores))
        if trial_scores[i] >= best_score - 1e-12:
            break
        best_score = trial_scores[i]
        current = [p.copy() if current is None else (c * size + p) / (size + 1) for c, p in
                   zip(current or [None] * len(preds[i]), preds[i])]
        counts[i] += 1
    return counts / max(1.0, counts.sum()), best_score


def out_of_fold(preds: list[list[np.ndarray]], fold_rmse: Callable[[np.ndarray, int], float],
                aggregate: Callable[[list[float]], float], steps: int = 25) -> tuple[float, float]:
    """Leave-one-fold-out scores (ensemble, single choice) of ``preds`` (per candidate: its per-fold predictions).

    For each fold k, the greedy weights and, separately, the one best candidate are chosen on the other folds
    alone and scored on fold k (``fold_rmse(prediction, k)``, µm); each list of out-of-fold RMSEs is aggregated.
    The greedy ensemble fits its weights to the folds it is scored on, so with two or three folds its in-sample
    score flatters it (members whose errors cancel on those folds); this is the honest comparison. Infinite
    with fewer than two folds."""
    n_folds = len(preds[0]) if preds else 0
    if n_folds < 2:
        return float("inf"), float("inf")
    rmse = [[fold_rmse(p[k], k) for k in range(n_folds)] for p in preds]
    ens, single = [], []
    for k in range(n_folds):
        others = [j for j in range(n_folds) if j != k]
        weights, _ = caruana([[p[j] for j in others] for p in preds],
                             lambda mix: aggregate([fold_rmse(m, j) for m, j in zip(mix, others)]), steps)
        ens.append(fold_rmse(sum(w * p[k] for w, p in zip(weights, preds) if w > 0), k))
        chosen = min(range(len(preds)), key=lambda i: (aggregate([rmse[i][j] for j in others]), i))
        single.append(rmse[chosen][k])
    return aggregate(ens), aggregate(single)
