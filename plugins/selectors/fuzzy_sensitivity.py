"""Selector ``fuzzy_sensitivity`` (S1): fuzzy clustering of the sensors, then the most sensitive one per class.

1. Fuzzy similarity R_ij = |Pearson r| between temperature series i and j.
2. Transitive closure t(R): R ← R∘R (max-min composition) until it no longer changes (R^(2^k)).
3. For every distinct level λ of t(R), the λ-cut {t(R) ≥ λ} is an equivalence relation; its classes are the
   candidate groupings. Each grouping into r classes (1 < r < n) gets the fuzzy-clustering F statistic
   F = [Σ_j n_j ‖x̄_j − x̄‖² / (r − 1)] / [Σ_j Σ_{i∈j} ‖x_i − x̄_j‖² / (n − r)] over the sensor series x_i
   centred on their means (°C, not scaled: Z-scored near-duplicates would make every split look significant);
   λ is where F peaks. A peak below the F distribution's (1 − ``significance``) quantile is no grouping at all:
   every sensor is its own class.
4. Global sensitivity: a small neural network maps (temperatures, temperature increments since the start) to
   the displacement increment; zeroing one sensor's increment changes the output, and the mean |change| over the
   samples is that sensor's index. The class's most sensitive sensor is selected.

``report_`` holds the tables (F for every λ, the classes, the sensitivity indices, the closure) and
:meth:`FuzzySensitivity.report_figures` draws the F curve and the sensitivities.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from thermodrift.core.components import Selector
from thermodrift.core.hookspecs import hookimpl

MAX_ROWS = 2000  # rows the sensitivity network trains on (evenly spaced), bounds its cost on long recordings


def similarity(X: pd.DataFrame) -> np.ndarray:
    """|Pearson r| between the columns of ``X`` (a constant column is similar only to itself)."""
    r = np.abs(np.nan_to_num(np.corrcoef(X.to_numpy(dtype=float), rowvar=False)))
    r = np.atleast_2d(r)
    np.fill_diagonal(r, 1.0)
    return r


def max_min(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Max-min composition (a∘b)_ij = max_k min(a_ik, b_kj)."""
    return np.minimum(a[:, :, None], b[None, :, :]).max(axis=1)


def transitive_closure(r: np.ndarray, max_steps: int = 64) -> np.ndarray:
    """t(R): square R under max-min composition until it no longer changes."""
    closure = np.asarray(r, dtype=float)
    for _ in range(max_steps):
        nxt = np.maximum(closure, max_min(closure, closure))
        if np.array_equal(nxt, closure):
            return closure
        closure = nxt
    raise RuntimeError("transitive closure did not converge")  # cannot happen for n ≤ 2^64 sensors


def lambda_cut(closure: np.ndarray, lam: float) -> np.ndarray:
    """Class label per sensor of the λ-cut of a transitive (equivalence) closure, numbered by first member."""
    labels = -np.ones(len(closure), dtype=int)
    for i in range(len(closure)):
        if labels[i] < 0:
            labels[(closure[i] >= lam - 1e-12) & (labels < 0)] = labels.max() + 1
    return labels


def f_statistic(series: np.ndarray, labels: np.ndarray) -> float:
    """Fuzzy-clustering F statistic of a grouping of the rows of ``series`` (sensors × samples)."""
    n, r = len(series), len(np.unique(labels))
    if not 1 < r < n:
        return float("nan")
    centre = series.mean(axis=0)
    between = within = 0.0
    for c in np.unique(labels):
        members = series[labels == c]
        mean = members.mean(axis=0)
        between += len(members) * float(((mean - centre) ** 2).sum())
        within += float(((members - mean) ** 2).sum())
    return (between / (r - 1)) / max(within / (n - r), 1e-300)


class FuzzySensitivity(Selector):
    """S1's fuzzy clustering + global sensitivity selector (see the module docstring).

    ``hidden_units``: neurons of the sensitivity network; ``significance``: level of the F test;
    ``max_classes``: only groupings with at most this many classes compete (None: all).
    """

    automl_cost = "skip"  # slow: it trains per fit

    def __init__(self, hidden_units: int = 10, significance: float = 0.05, max_classes: int | None = None,
                 random_state: int = 0):
        self.hidden_units = hidden_units
        self.significance = significance
        self.max_classes = max_classes
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        return [{"hidden_units": 4}, {"hidden_units": 6, "significance": 0.1, "max_classes": 2, "random_state": 3}]

    def _select(self, X, y):
        from scipy.stats import f as f_dist

        cols = list(X.columns)
        series = X.to_numpy(dtype=float).T
        series = series - series.mean(axis=1, keepdims=True)
        closure = transitive_closure(similarity(X))
        levels = np.unique(np.round(closure, 12))[::-1]  # rounding merges levels equal up to float noise
        rows, best = [], (-np.inf, np.arange(len(cols)), float("nan"))
        for lam in levels:
            labels = lambda_cut(closure, lam)
            f = f_statistic(series, labels)
            r = len(np.unique(labels))
            crit = float(f_dist.ppf(1 - self.significance, r - 1, len(cols) - r)) if 1 < r < len(cols) else np.nan
            rows.append({"lambda": float(lam), "classes": r, "F": f, "F_critical": crit})
            allowed = self.max_classes is None or r <= self.max_classes
            if allowed and np.isfinite(f) and f > crit and f > best[0]:
                best = (f, labels, float(lam))
        self.lambda_ = best[2]
        self.classes_ = {c: int(k) for c, k in zip(cols, best[1])}
        sens = self._sensitivity(X, y)
        chosen = []
        for k in sorted(set(self.classes_.values())):
            members = [i for i, c in enumerate(cols) if self.classes_[c] == k]
            chosen.append(cols[max(members, key=lambda i: (sens[i], -i))])
        self.sensitivity_ = dict(zip(cols, map(float, sens)))
        self.report_ = {
            "fuzzy_f_by_lambda": pd.DataFrame(rows),
            "fuzzy_classes": pd.DataFrame({"sensor": cols, "class": best[1], "sensitivity": sens,
                                           "selected": [c in chosen for c in cols]}),
            "fuzzy_closure": pd.DataFrame(closure, index=cols, columns=cols),
        }
        return [c for c in cols if c in chosen]

    def _sensitivity(self, X: pd.DataFrame, y) -> np.ndarray:
        """Mean |output change| of the (T, ΔT) → Δy network when one sensor's ΔT is zeroed (µm)."""
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.neural_network import MLPRegressor

        t = X.to_numpy(dtype=float)
        target = np.asarray(y, dtype=float).reshape(len(t), -1)
        if len(t) > MAX_ROWS:
            keep = np.linspace(0, len(t) - 1, MAX_ROWS).round().astype(int)
            t, target = t[keep], target[keep]
        dt, dy = t - t[0], target - target[0]
        inputs = np.hstack([t, dt])
        mean, scale = inputs.mean(axis=0), inputs.std(axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        net = MLPRegressor(hidden_layer_sizes=(self.hidden_units,), solver="lbfgs", max_iter=300,
                           random_state=self.random_state)
        with warnings.catch_warnings():  # a fixed iteration budget is the stopping rule, not a failure
            warnings.simplefilter("ignore", ConvergenceWarning)
            net.fit((inputs - mean) / scale, dy if dy.shape[1] > 1 else dy[:, 0])
        base = net.predict((inputs - mean) / scale).reshape(len(t), -1)
        out = np.zeros(t.shape[1])
        for i in range(t.shape[1]):
            zeroed = inputs.copy()
            zeroed[:, t.shape[1] + i] = 0.0
            out[i] = np.abs(net.predict((zeroed - mean) / scale).reshape(len(t), -1) - base).mean()
        return out

    def report_figures(self) -> dict:
        """The F statistic over λ and the sensitivity index per sensor (matplotlib Figures)."""
        from matplotlib.figure import Figure

        fig = Figure(figsize=(9, 3.4))
        ax1, ax2 = fig.subplots(1, 2)
        f = self.report_["fuzzy_f_by_lambda"]
        ax1.plot(f["lambda"], f["F"], "o-", label="F")
        ax1.plot(f["lambda"], f["F_critical"], "--", color="grey", label="F critical")
        if np.isfinite(self.lambda_):
            ax1.axvline(self.lambda_, color="red", lw=0.8, label=f"λ = {self.lambda_:.4f}")
        ax1.set_xlabel("λ")
        ax1.set_ylabel("F statistic")
        ax1.legend(fontsize=7)
        c = self.report_["fuzzy_classes"]
        ax2.bar(c["sensor"].astype(str), c["sensitivity"], color=["C3" if s else "C0" for s in c["selected"]])
        ax2.set_ylabel("sensitivity index [µm]")
        ax2.tick_params(axis="x", rotation=90, labelsize=7)
        return {"fuzzy_sensitivity.png": fig}


@hookimpl
def thermodrift_register_selectors(registry):
    registry.add("selector", "fuzzy_sensitivity", FuzzySensitivity)
