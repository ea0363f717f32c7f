"""Selector ``hdbscan_pso``: it finds the sensor group that follows the error, reports S3's tables, swaps its tuner,
and survives scikit-learn's epsilon bug."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from thermodrift.plugins.selectors.hdbscan_pso import HDBSCANPSO, _epsilon_merge, bwp


def _sensors(seed=0, n=400):
    """Three groups of sensors: four follow a slow heating (the drift follows it), four a daily ambient swing,
    three a coolant on/off cycle; one sensor is noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    heat = 1 - np.exp(-t / 120.0)
    ambient = np.sin(2 * np.pi * t / 250.0)
    coolant = np.sign(np.sin(2 * np.pi * t / 60.0))
    cols = {}
    for i in range(4):
        cols[f"H{i}"] = 20 + (5 + i) * heat + rng.normal(0, 0.05, n)
    for i in range(4):
        cols[f"A{i}"] = 20 + (1 + 0.2 * i) * ambient + rng.normal(0, 0.05, n)
    for i in range(3):
        cols[f"C{i}"] = 18 + (0.5 + 0.1 * i) * coolant + rng.normal(0, 0.05, n)
    cols["N0"] = 20 + rng.normal(0, 1, n)
    X = pd.DataFrame(cols)
    y = pd.DataFrame({"z_um": 12 * heat + 0.3 * ambient + rng.normal(0, 0.1, n)})
    return X, y


@pytest.mark.parametrize("optimizer", ["pso", "gwo", "fa"])
def test_selects_the_group_that_follows_the_error(optimizer):
    X, y = _sensors()
    sel = HDBSCANPSO(optimizer=optimizer, optimizer_params={"population_size": 8}, n_iterations=10).fit(X, y)
    assert sel.selected_ == ["H0", "H1", "H2", "H3"]
    assert sel.fitness_ > 0.95 and set(sel.best_params_) == {"min_samples", "min_cluster_size", "alpha",
                                                              "cluster_selection_epsilon"}


def test_report_holds_s3s_tables_and_a_figure():
    X, y = _sensors()
    sel = HDBSCANPSO(optimizer_params={"population_size": 8}, n_iterations=6).fit(X, y)
    clusters, quality = sel.report_["clusters"], sel.report_["quality"]
    assert {"members", "pearson", "spearman", "kendall", "rank_pearson", "rank_spearman", "rank_kendall"} <= set(
        clusters.columns)
    assert clusters.iloc[0]["members"] == "H0,H1,H2,H3" and clusters.iloc[0]["rank_pearson"] == 1
    assert list(quality.index) == ["default", "tuned"]
    assert {"davies_bouldin", "silhouette", "bwp", "fitness"} <= set(quality.columns)
    assert quality.loc["tuned", "fitness"] >= quality.loc["default", "fitness"]
    conv = sel.report_["convergence"]["best_fitness"]
    assert len(conv) == 6 and conv.is_monotonic_increasing
    assert set(sel.report_["best_params"].columns) == set(sel.best_params_)
    assert all(isinstance(t, pd.DataFrame) for t in sel.report_.values())
    assert len(sel.report_figures()["hdbscan_pso.png"].axes) == 2


def test_s3s_pso_is_the_default_tuner():
    sel = HDBSCANPSO()
    assert sel._sampler_params() == {"population_size": 20, "form": "inertia", "w_start": 0.729, "w_end": 0.729,
                                     "c1": 1.494, "c2": 1.494}
    assert sel.n_iterations * sel._population() == 500  # the paper's 100 iterations: n_iterations=100


def test_epsilon_merge_joins_clusters_that_split_below_epsilon():
    eom = np.array([0, 0, 1, 1, 2, 2, -1])
    cut = np.array([0, 0, 0, 0, 1, 1, 0])  # at epsilon, clusters 0 and 1 (and the noise point) are one
    assert _epsilon_merge(eom, cut).tolist() == [1, 1, 1, 1, 0, 0, 1]


def test_bwp_is_one_for_tight_far_apart_clusters_and_falls_when_they_overlap():
    tight = np.array([[0.0], [0.01], [10.0], [10.01]])
    assert bwp(tight, np.array([0, 0, 1, 1])) > 0.99
    mixed = bwp(tight, np.array([0, 1, 0, 1]))
    assert mixed < 0
