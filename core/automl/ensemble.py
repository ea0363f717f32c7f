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
