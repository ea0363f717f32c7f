"""Selector ``variance_top_k``: keep the ``k`` temperature channels (°C) that vary most over the recording."""

import numpy as np

from thermodrift.core.components import Selector
from thermodrift.core.hookspecs import hookimpl


class VarianceTopK(Selector):
    """Keep the ``k`` channels with the largest temperature variance (°C²); all of them if there are fewer."""

    def __init__(self, k: int = 3):
        self.k = k

    @classmethod
    def get_test_params(cls):
        return [{"k": 2}, {"k": 3}]

    def _select(self, X, y):
        if self.k >= X.shape[1]:
            return list(X.columns)
        variance = X.to_numpy(dtype=float).var(axis=0)
        best = np.argsort(-variance, kind="stable")[: self.k]
        return [X.columns[i] for i in sorted(best)]


@hookimpl
def thermodrift_register_selectors(registry):
    registry.add("selector", "variance_top_k", VarianceTopK)
