"""Selector ``gra_hierarchical`` (S2): grey relational analysis, hierarchical clustering, then one per group.

1. Grey relational grade of each temperature with the displacement: both min-max normalised over time,
   Δ_i(t) = |y(t) − x_i(t)|, coefficient ξ_i(t) = (Δmin + ρ Δmax) / (Δ_i(t) + ρ Δmax) with Δmin, Δmax over all
   sensors and samples and ρ = ``rho`` (0.5); the grade is the mean coefficient. The ``top_m`` best are kept.
2. Those are clustered hierarchically (distance 1 − |Pearson r|, ``linkage`` linkage) into ``n_groups`` groups.
3. Groups are visited in order of their best |r| with the displacement; in each, the sensor that maximises the
   compound (adjusted) coefficient R'² = 1 − (n − 1)/(n − i − 1)·(1 − R²) of the linear regression of the
   displacement on the sensors chosen so far plus that sensor is taken (n samples, i regressors).

With several displacement channels, grades, correlations and R² are averaged over the channels.
``report_`` holds the grades, the groups and the R'² path; :meth:`GRAHierarchical.report_figures` draws them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from thermodrift.core.components import Selector
from thermodrift.core.hookspecs import hookimpl


def _minmax(a: np.ndarray) -> np.ndarray:
    span = a.max(axis=0) - a.min(axis=0)
    return (a - a.min(axis=0)) / np.where(span > 0, span, 1.0)


def grey_grades(X: np.ndarray, y: np.ndarray, rho: float = 0.5) -> np.ndarray:
    """Grey relational grade of each column of ``X`` with each column of ``y``, averaged over ``y``'s columns."""
    x = _minmax(X)
    grades = []
    for k in range(y.shape[1]):
        delta = np.abs(_minmax(y[:, [k]]) - x)
        lo, hi = delta.min(), delta.max()
        coef = (lo + rho * hi) / (delta + rho * hi) if hi > 0 else np.ones_like(delta)
        grades.append(coef.mean(axis=0))
    return np.mean(grades, axis=0)


def adjusted_r2(X: np.ndarray, y: np.ndarray) -> float:
    """Compound coefficient R'² = 1 − (n−1)/(n−i−1)(1−R²) of least squares y ~ X, mean over y's columns."""
    n, i = X.shape
    A = np.hstack([np.ones((n, 1)), X])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    res = ((y - A @ coef) ** 2).sum(axis=0)
    tot = ((y - y.mean(axis=0)) ** 2).sum(axis=0)
    r2 = 1 - res / np.where(tot > 0, tot, 1.0)
    return float(np.mean(1 - (n - 1) / max(n - i - 1, 1) * (1 - r2)))


class GRAHierarchical(Selector):
    """S2's grey relational analysis + hierarchical clustering selector (see the module docstring)."""

    def __init__(self, top_m: int = 8, n_groups: int = 5, rho: float = 0.5, linkage: str = "average"):
        self.top_m = top_m
        self.n_groups = n_groups
        self.rho = rho
        self.linkage = linkage

    @classmethod
    def get_test_params(cls):
        return [{"top_m": 3, "n_groups": 2}, {"top_m": 4, "n_groups": 3, "rho": 0.3, "linkage": "complete"}]

    def _select(self, X, y):
        from scipy.cluster.hierarchy import fcluster, linkage
        from scipy.spatial.distance import squareform

        if self.top_m < 1 or self.n_groups < 1 or not 0 < self.rho <= 1:
            raise ValueError("top_m and n_groups must be >= 1 and rho in (0, 1]")
        cols = list(X.columns)
        x = X.to_numpy(dtype=float)
        t = np.asarray(y, dtype=float).reshape(len(x), -1)
        grades = grey_grades(x, t, self.rho)
        kept = sorted(np.argsort(-grades, kind="stable")[:self.top_m])
        corr = np.nan_to_num(np.corrcoef(np.hstack([x[:, kept], t]), rowvar=False))
        m = len(kept)
        r_err = np.abs(corr[:m, m:]).mean(axis=1)
        if m > 1:
            dist = np.clip(1 - np.abs(corr[:m, :m]), 0, None)
            np.fill_diagonal(dist, 0.0)
            tree = linkage(squareform((dist + dist.T) / 2, checks=False), method=self.linkage)
            groups = fcluster(tree, t=min(self.n_groups, m), criterion="maxclust")
        else:
            groups = np.ones(1, dtype=int)
        order = sorted(set(groups), key=lambda g: -r_err[groups == g].max())
        chosen: list[int] = []
        path = []
        for g in order:
            members = np.flatnonzero(groups == g)
            scores = [adjusted_r2(x[:, [kept[j] for j in chosen] + [kept[i]]], t) for i in members]
            pick = int(members[int(np.argmax(scores))])
            chosen.append(pick)
            path.append({"group": int(g), "sensor": cols[kept[pick]], "abs_r_with_error": float(r_err[pick]),
                         "compound_r2": float(max(scores))})
        self.grades_ = dict(zip(cols, map(float, grades)))
        self.groups_ = {cols[kept[i]]: int(groups[i]) for i in range(m)}
        self.report_ = {
            "gra_grades": pd.DataFrame({"sensor": cols, "grey_grade": grades,
                                        "kept": [i in kept for i in range(len(cols))]}),
            "gra_groups": pd.DataFrame({"sensor": [cols[k] for k in kept], "group": groups,
                                        "abs_r_with_error": r_err}),
            "gra_selection_path": pd.DataFrame(path),
        }
        return [cols[k] for k in sorted(kept[i] for i in chosen)]

    def report_figures(self) -> dict:
        """Grey relational grades (kept sensors highlighted) and the R'² path (matplotlib Figures)."""
        from matplotlib.figure import Figure

        fig = Figure(figsize=(9, 3.4))
        ax1, ax2 = fig.subplots(1, 2)
        g = self.report_["gra_grades"]
        ax1.bar(g["sensor"].astype(str), g["grey_grade"], color=["C3" if k else "C0" for k in g["kept"]])
        ax1.set_ylabel("grey relational grade")
        ax1.tick_params(axis="x", rotation=90, labelsize=7)
        p = self.report_["gra_selection_path"]
        ax2.plot(range(1, len(p) + 1), p["compound_r2"], "o-")
        ax2.set_xticks(range(1, len(p) + 1), p["sensor"].astype(str), rotation=90, fontsize=7)
        ax2.set_ylabel("compound coefficient R'²")
        return {"gra_hierarchical.png": fig}


@hookimpl
def thermodrift_register_selectors(registry):
    registry.add("selector", "gra_hierarchical", GRAHierarchical)
