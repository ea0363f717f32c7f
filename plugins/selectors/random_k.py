"""Selector ``random_k``: k temperature channels drawn at random (the control in S3's selection study)."""

import numpy as np

from thermodrift.core.components import Selector
from thermodrift.core.hookspecs import hookimpl


class RandomK(Selector):
    """Keep ``k`` channels drawn uniformly with ``random_state``; all of them if there are fewer."""

    automl_cost = "skip"  # random: no evidence for a choice

    def __init__(self, k: int = 4, random_state: int = 0):
        self.k = k
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        return [{"k": 2, "random_state": 0}, {"k": 3, "random_state": 7}]

    @classmethod
    def search_space(cls):
        return {"k": {"type": "int", "low": 1, "high": 16}}

    def _select(self, X, y):
        cols = list(X.columns)
        if self.k >= len(cols):
            return cols
        picked = np.random.default_rng(self.random_state).choice(len(cols), size=self.k, replace=False)
        return [cols[i] for i in sorted(picked)]


@hookimpl
def thermodrift_register_selectors(registry):
    registry.add("selector", "random_k", RandomK)
