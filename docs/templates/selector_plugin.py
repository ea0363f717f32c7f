"""Template: a thermodrift selector plugin (which temperature sensors feed the model) in one file.

How to use:
1. Copy this file into your package, e.g. ``my_selectors/top_k_r.py``, and rename class and registry name.
2. Fill in the ``todo`` parts. Keep the rules: ``__init__`` only stores its arguments; ``_select`` returns a
   non-empty list of column names of ``X``; the same seed gives the same selection; selecting again from the
   selected columns keeps all of them (so with fewer columns than you would keep, keep them all).
3. One entry-point line in your ``pyproject.toml``::

       [project.entry-points.thermodrift]
       top_k_r = "my_selectors.top_k_r"

4. ``thermodrift run selector=top_k_r`` works with no YAML: its config is built from the registry
   (``params`` = the constructor's defaults). For other defaults ship ``my_selectors/conf/selector/top_k_r.yaml``
   and add ``registry.add_searchpath("pkg://my_selectors.conf")`` in a ``thermodrift_hydra_searchpaths`` hook.
5. Check it: ``from thermodrift.testing import check_component; check_component("selector", "top_k_r")``
   or subclass ``thermodrift.testing.pytest_components.SelectorTests`` with ``name = "top_k_r"``.

The example keeps the k sensors whose temperature (°C) correlates best with any displacement channel (µm).
"""

import numpy as np

from thermodrift.core.components import Selector
from thermodrift.core.hookspecs import hookimpl


# todo: rename the class and say what it keeps
class TopKCorrelation(Selector):
    """Keep the ``k`` channels with the largest |Pearson r| with a displacement channel; all if there are fewer."""

    # todo: one argument per hyperparameter (add random_state if anything is random); store them unchanged
    def __init__(self, k: int = 4):
        self.k = k

    # todo: at least two cheap parameter sets for the conformance suite
    @classmethod
    def get_test_params(cls):
        return [{"k": 2}, {"k": 3}]

    # todo: X is a DataFrame of temperatures (°C), y of displacements (µm), both indexed by time (s)
    def _select(self, X, y):
        if self.k >= X.shape[1]:
            return list(X.columns)
        x, t = X.to_numpy(dtype=float), np.asarray(y, dtype=float).reshape(len(y), -1)
        r = np.nan_to_num(np.corrcoef(np.hstack([x, t]), rowvar=False))[: x.shape[1], x.shape[1]:]
        best = np.argsort(-np.abs(r).max(axis=1), kind="stable")[: self.k]
        return [X.columns[i] for i in sorted(best)]


# todo: the registry name users type in `thermodrift run selector=<name>`
@hookimpl
def thermodrift_register_selectors(registry):
    registry.add("selector", "top_k_r", TopKCorrelation)

