"""Selector ``hdbscan_pso``: HDBSCAN over the sensors with its hyper-parameters tuned by a metaheuristic (study S3).

Each sensor is one point: its Z-scored series over the training rows, so the Euclidean distance between two sensors
is sqrt(2 n (1 - r)) for their Pearson r (correlation distance; scaled by 1/sqrt(2n) here). scikit-learn's HDBSCAN
clusters the points (noise sensors belong to no cluster); a cluster's signal is the mean of its members' Z-scored
series. An inner Optuna study tunes min_samples (2-20), min_cluster_size (2-20), alpha (0.5-2.0) and
cluster_selection_epsilon (0-0.5) with any registered optimizer (default: S3's PSO, w 0.729, c1 = c2 = 1.494,
swarm 20), fitness the largest |Pearson r| between a cluster's signal and the error (mean over displacement
channels). A setting that leaves every sensor as noise (with 16 sensors, any min_samples above about 4) scores
below every clustering, the lower the larger min_samples + min_cluster_size, so the search has a slope to follow
instead of a plateau of zeros. The selection is the best cluster of the tuned clustering.

S3 runs 100 iterations (2,000 trials); the default here is 25 iterations (500 trials, a few seconds on a CPU);
``n_iterations=100`` restores the paper's budget (``selector.params.n_iterations=100``).

After ``fit``, ``report_`` holds the tables of S3's selection study: ``clusters`` (members and |r| by Pearson,
Spearman and Kendall, with each ranking), ``quality`` (Davies-Bouldin, silhouette and BWP of scikit-learn's
default HDBSCAN against the tuned one), ``convergence`` (best fitness after each iteration) and ``best_params``,
all DataFrames; :meth:`report_figures` draws them (the selector-report convention that the job logs to MLflow).
``metrics_`` holds S3 Table 16's scalars, logged as ``selector/<name>``: ``best_fitness`` (|r|) and
``best_iteration`` (the first iteration that reached it).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import optuna
import pandas as pd
from scipy import stats

from thermodrift.core.components import Selector
from thermodrift.core.hookspecs import hookimpl

# S3's search space for the clustering
SPACE = {"min_samples": (2, 20), "min_cluster_size": (2, 20), "alpha": (0.5, 2.0),
         "cluster_selection_epsilon": (0.0, 0.5)}
# S3's PSO: constant inertia 0.729, c1 = c2 = 1.494, swarm 20 (conf/optimizer/pso_s3.yaml)
S3_PSO = {"population_size": 20, "form": "inertia", "w_start": 0.729, "w_end": 0.729, "c1": 1.494, "c2": 1.494}


class HDBSCANPSO(Selector):
    """Keep the sensors of the tuned HDBSCAN cluster most correlated with the error (see the module docstring).

    Args:
        optimizer: a registered optimizer name (``pso``, ``gwo``, ``fa``, ``rbmox``, ``tpe``, ...).
        optimizer_params: its parameters; None gives S3's PSO settings for ``pso`` and the optimizer's defaults else.
        n_iterations: iterations of the population (trials = n_iterations x population size; 25 for a population-free
            optimizer's 20-trial "iteration").
        random_state: seed of the inner study.
    """

    automl_cost = "skip"  # slow: a swarm per fit

    def __init__(self, optimizer: str = "pso", optimizer_params: dict | None = None, n_iterations: int = 25,
                 random_state: int = 0):
        self.optimizer = optimizer
        self.optimizer_params = optimizer_params
        self.n_iterations = n_iterations
        self.random_state = random_state

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"n_iterations": 3, "optimizer_params": {"population_size": 5}},
                {"optimizer": "gwo", "optimizer_params": {"population_size": 4}, "n_iterations": 3}]

    # ------------------------------------------------------------------------------------------------ selection
    def _select(self, X: pd.DataFrame, y: pd.DataFrame) -> list[str]:
        names = list(X.columns)
        points = _points(X)
        target = np.asarray(y, dtype=float).reshape(len(y), -1)
        if len(names) < 3:  # nothing to cluster: every sensor is the selection
            self.labels_ = np.zeros(len(names), dtype=int)
            self.best_params_, self.fitness_ = {}, _fitness(points, self.labels_, target)
            self.report_ = {"clusters": _cluster_table(names, points, self.labels_, target), "quality": pd.DataFrame(),
                            "convergence": pd.DataFrame({"best_fitness": []}), "best_params": pd.DataFrame()}
            self.metrics_ = {"best_fitness": self.fitness_, "best_iteration": 0.0}
            return names
        study = self._tune(points, target)
        self.best_params_ = dict(study.best_params)
        self.labels_ = _cluster(points, **self.best_params_)
        self.fitness_ = float(study.best_value)
        default_labels = _cluster(points, **_sklearn_defaults(len(names)))
        clusters = _cluster_table(names, points, self.labels_, target)
        convergence = _convergence(study, self._population())
        reached = convergence.index[np.argmax(convergence.to_numpy() >= convergence.max() - 1e-12)]
        self.metrics_ = {"best_fitness": self.fitness_, "best_iteration": float(reached)}
        self.report_ = {
            "clusters": clusters,
            "quality": pd.DataFrame({"default": _quality(points, default_labels, target),
                                     "tuned": _quality(points, self.labels_, target)}).T,
            "convergence": convergence.to_frame(),
            "best_params": pd.DataFrame([self.best_params_], index=pd.Index(["tuned"], name="clustering")),
        }
        if clusters.empty:  # every sensor is noise under every tried setting
            return names
        best = clusters.index[clusters["rank_pearson"] == 1][0]
        return [n for n, lab in zip(names, self.labels_) if lab == best]

    def _population(self) -> int:
        params = self._sampler_params()
        return int(params.get("population_size", 20))

    def _sampler_params(self) -> dict:
        if self.optimizer_params is not None:
            return dict(S3_PSO, **self.optimizer_params) if self.optimizer == "pso" else dict(self.optimizer_params)
        return dict(S3_PSO) if self.optimizer == "pso" else {}

    def _tune(self, points: np.ndarray, target: np.ndarray) -> optuna.Study:
        from thermodrift.core import registry

        n_trials = self.n_iterations * self._population()
        sampler = registry.create_sampler(self.optimizer, seed=self.random_state, n_trials=n_trials,
                                          **self._sampler_params())
        high = len(points) - 1  # HDBSCAN needs min_samples and min_cluster_size below the number of points

        def objective(trial: optuna.Trial) -> float:
            params = {name: (trial.suggest_int(name, *bounds) if isinstance(bounds[0], int)
                             else trial.suggest_float(name, *bounds)) for name, bounds in SPACE.items()}
            labels = _cluster(points, **_capped(params, high))
            if labels.max() < 0:  # all noise: a fitness below every clustering's, rising toward smaller settings
                return -(params["min_samples"] + params["min_cluster_size"]) / (4 * SPACE["min_samples"][1])
            return _fitness(points, labels, target)

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        study = optuna.create_study(direction="maximize", sampler=sampler)
        study.optimize(objective, n_trials=n_trials)
        study.best_params  # raises if no trial completed
        return study

    # ------------------------------------------------------------------------------------------------ report
    def report_figures(self) -> dict:
        """``{"hdbscan_pso.png": Figure}``: cluster ranking and the inner search's convergence (outside pyplot)."""
        from matplotlib.figure import Figure

        fig = Figure(figsize=(10, 3.6))
        left, right = fig.subplots(1, 2)
        table = self.report_["clusters"]
        if not table.empty:
            x = np.arange(len(table))
            for i, method in enumerate(("pearson", "spearman", "kendall")):
                left.bar(x + (i - 1) * 0.27, table[method], width=0.27, label=method.capitalize())
            left.set_xticks(x, [f"C{c}\n({len(m.split(','))})" for c, m in zip(table.index, table["members"])])
        left.set_ylabel("|correlation| with the error")
        left.set_title("clusters (sensors)")
        left.legend(fontsize=7)
        conv = self.report_["convergence"]["best_fitness"]
        right.plot(conv.index, conv.to_numpy(), marker="o", ms=3)
        right.set_xlabel("iteration")
        right.set_ylabel("best fitness (|Pearson r|)")
        right.set_title(f"{self.optimizer} on HDBSCAN's hyper-parameters")
        return {"hdbscan_pso.png": fig}


# ---------------------------------------------------------------------------------------------------- helpers
def _points(X: pd.DataFrame) -> np.ndarray:
    """One row per sensor: its series Z-scored and divided by sqrt(2n), so distances are sqrt(1 - r)."""
    x = X.to_numpy(dtype=float)
    std = x.std(axis=0)
    z = (x - x.mean(axis=0)) / np.where(std > 0, std, 1.0)
    return z.T / np.sqrt(2 * len(x))


def _capped(params: dict, high: int) -> dict:
    out = dict(params)
    for key in ("min_samples", "min_cluster_size"):
        out[key] = min(out[key], high)
    return out


def _sklearn_defaults(n_points: int) -> dict:
    """scikit-learn's default HDBSCAN (min_cluster_size 5, min_samples = min_cluster_size, alpha 1, epsilon 0)."""
    size = min(5, n_points - 1)
    return {"min_cluster_size": size, "min_samples": size, "alpha": 1.0, "cluster_selection_epsilon": 0.0}


def _cluster(points: np.ndarray, **params) -> np.ndarray:
    """HDBSCAN labels of the sensors (-1 = noise)."""
    from sklearn.cluster import HDBSCAN

    params = _capped(params, len(points) - 1)
    params["min_cluster_size"] = max(2, params["min_cluster_size"])
    try:
        return HDBSCAN(copy=True, **params).fit(points).labels_
    except TypeError:
        # scikit-learn's epsilon merge raises under NumPy 2 whenever it has to merge (scikit-learn#33219, fixed
        # upstream, not released for 1.9): merge from the same single-linkage tree through its public DBSCAN* cut.
        eps = params.pop("cluster_selection_epsilon")
        fitted = HDBSCAN(copy=True, **params).fit(points)
        return _epsilon_merge(fitted.labels_, fitted.dbscan_clustering(eps, params["min_cluster_size"]))


def _epsilon_merge(eom: np.ndarray, cut: np.ndarray) -> np.ndarray:
    """Malzer & Baum's epsilon rule on flat labels: EOM clusters that split below epsilon (they share one DBSCAN*
    cluster of the cut at epsilon) become that DBSCAN* cluster; the other EOM clusters stay."""
    out = eom.copy()
    next_label = eom.max() + 1
    for d in sorted(set(cut.tolist()) - {-1}):
        inside = cut == d
        parts = set(eom[inside].tolist()) - {-1}
        if len(parts) >= 2:
            out[inside | np.isin(eom, list(parts))] = next_label
            next_label += 1
    _, relabelled = np.unique(np.where(out >= 0, out, -1), return_inverse=True)
    return np.where(out >= 0, relabelled - (out < 0).any(), -1)


def _signals(points: np.ndarray, labels: np.ndarray) -> dict[int, np.ndarray]:
    """Cluster id -> the mean of its members' Z-scored series (noise, label -1, is no cluster)."""
    return {int(c): points[labels == c].mean(axis=0) for c in sorted(set(labels.tolist())) if c >= 0}


def _abs_corr(method: str, signal: np.ndarray, target: np.ndarray) -> float:
    """Mean over displacement channels of |r| between ``signal`` and each channel (0 for a constant series)."""
    fn = {"pearson": stats.pearsonr, "spearman": stats.spearmanr, "kendall": stats.kendalltau}[method]
    if np.ptp(signal) == 0:
        return 0.0
    values = [abs(float(fn(signal, t).statistic)) if np.ptp(t) > 0 else 0.0 for t in target.T]
    return float(np.nan_to_num(np.mean(values)))


def _fitness(points: np.ndarray, labels: np.ndarray, target: np.ndarray) -> float:
    """The largest |Pearson r| between a cluster's signal and the error; 0 when every sensor is noise."""
    signals = _signals(points, labels)
    return max((_abs_corr("pearson", s, target) for s in signals.values()), default=0.0)


def _cluster_table(names: list[str], points: np.ndarray, labels: np.ndarray, target: np.ndarray) -> pd.DataFrame:
    rows = {}
    for c, signal in _signals(points, labels).items():
        members = [n for n, lab in zip(names, labels) if lab == c]
        rows[c] = {"members": ",".join(members), "size": len(members),
                   **{m: _abs_corr(m, signal, target) for m in ("pearson", "spearman", "kendall")}}
    table = pd.DataFrame.from_dict(rows, orient="index")
    if table.empty:
        return table
    for m in ("pearson", "spearman", "kendall"):  # rank 1 = most correlated; ties to the lower cluster id
        table[f"rank_{m}"] = table[m].rank(ascending=False, method="first").astype(int)
    table.index.name = "cluster"
    return table.sort_values("rank_pearson")


def bwp(points: np.ndarray, labels: np.ndarray) -> float:
    """Mean between-within proportion (Zhou et al.): per point (b - w) / (b + w), w its mean distance to the rest
    of its own cluster (0 for a singleton), b the smallest mean distance to another cluster; label -1 left out;
    NaN with fewer than two clusters. scikit-learn has no BWP, hence written here."""
    keep = labels >= 0
    p, lab = points[keep], labels[keep]
    clusters = sorted(set(lab.tolist()))
    if len(clusters) < 2:
        return float("nan")
    dist = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=-1)
    scores = []
    for i in range(len(p)):
        own = (lab == lab[i]) & (np.arange(len(p)) != i)
        w = dist[i, own].mean() if own.any() else 0.0
        b = min(dist[i, lab == c].mean() for c in clusters if c != lab[i])
        scores.append((b - w) / (b + w) if b + w > 0 else 0.0)
    return float(np.mean(scores))


def _quality(points: np.ndarray, labels: np.ndarray, target: np.ndarray) -> dict[str, float]:
    """Davies-Bouldin (lower is better), silhouette and BWP (higher is better) over every sensor, each noise sensor
    counted as a cluster of its own (so one cluster plus noise is scored too); NaN where the partition has fewer
    than two groups or no group of two."""
    from sklearn.metrics import davies_bouldin_score, silhouette_score

    n_clusters = len(set(labels[labels >= 0].tolist()))
    groups = labels.copy()
    groups[labels < 0] = n_clusters + np.arange((labels < 0).sum())
    ok = 2 <= len(set(groups.tolist())) < len(groups)
    return {"n_clusters": float(n_clusters), "n_noise": float((labels < 0).sum()),
            "davies_bouldin": float(davies_bouldin_score(points, groups)) if ok else float("nan"),
            "silhouette": float(silhouette_score(points, groups)) if ok else float("nan"),
            "bwp": bwp(points, groups) if ok else float("nan"), "fitness": _fitness(points, labels, target)}


def _convergence(study: optuna.Study, population: int) -> pd.Series:
    """Best fitness after each iteration (``population`` trials), indexed 1, 2, ..."""
    values = np.array([t.value if t.value is not None else -np.inf for t in study.trials])
    best = np.maximum.accumulate(values)
    ends = np.arange(population, len(best) + population, population).clip(max=len(best))
    return pd.Series(best[ends - 1], index=pd.RangeIndex(1, len(ends) + 1, name="iteration"), name="best_fitness")


@hookimpl
def thermodrift_register_selectors(registry):
    registry.add("selector", "hdbscan_pso", HDBSCANPSO)
