"""Selector ``correlation_top_k``: the k temperatures most correlated with the displacement, least redundant.

Greedy: rank channels by the largest |Pearson r| with any displacement channel, then skip a channel whose
|r| with an already chosen one exceeds ``max_mutual_r`` (collinear sensors add little and destabilise MLR).
"""

import numpy as np

from thermodrift.core.components import Selector
from thermodrift.core.hookspecs import hookimpl


class CorrelationTopK(Selector):
    """Keep up to ``k`` channels by |Pearson r| with the target, dropping near-duplicates (|r| > max_mutual_r)."""

    def __init__(self, k: int = 4, max_mutual_r: float = 0.995):
        self.k = k
        self.max_mutual_r = max_mutual_r

    @classmethod
    def get_test_params(cls):
        return [{"k": 2}, {"k": 3, "max_mutual_r": 0.9}]

    @classmethod
    def search_space(cls):
        return {"k": {"type": "int", "low": 1, "high": 16}}

    def _select(self, X, y):
        x = X.to_numpy(dtype=float)
        t = np.asarray(y, dtype=float).reshape(len(y), -1)
        corr = np.nan_to_num(np.corrcoef(np.hstack([x, t]), rowvar=False))
        n = x.shape[1]
        score = np.abs(corr[:n, n:]).max(axis=1)
        chosen: list[int] = []
        for i in np.argsort(-score, kind="stable"):
            if len(chosen) == self.k:
                break
            if all(abs(corr[i, j]) <= self.max_mutual_r for j in chosen):
                chosen.append(int(i))
        return [X.columns[i] for i in sorted(chosen)]


@hookimpl
def thermodrift_register_selectors(registry):
    registry.add("selector", "correlation_top_k", CorrelationTopK)
