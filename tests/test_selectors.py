"""The published studies' selectors on recordings whose answer is known: S1's fuzzy sensitivity and S2's grey
relational analysis; ``hdbscan_pso`` (S3): it finds the sensor group that follows the error, reports S3's tables,
swaps its tuner, and survives scikit-learn's epsilon bug."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from thermodrift.plugins.selectors.fuzzy_sensitivity import (FuzzySensitivity, lambda_cut, max_min, similarity,
                                                              transitive_closure)
from thermodrift.plugins.selectors.gra_hierarchical import GRAHierarchical, grey_grades
from thermodrift.plugins.selectors.hdbscan_pso import HDBSCANPSO, _epsilon_merge, bwp


def _grouped_recording(seed=0, n=600):
    """Three independent heat sources, three sensors on each (gains within 10 %); drift from all three."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 60.0
    sources = []
    for k in range(3):
        u = np.cumsum(rng.normal(0, 1, n))  # independent slow random heat input
        sources.append(np.convolve(u, np.ones(20) / 20, mode="same"))
    X, groups = {}, {}
    for k, s in enumerate(sources):
        for j in range(3):
            name = f"T{k}{j}"
            X[name] = 20 + (0.9 + 0.1 * j) * s + rng.normal(0, 0.05, n)
            groups[name] = k
    y = pd.DataFrame({"disp_um": 3 * sources[0] - 2 * sources[1] + 1.5 * sources[2]}, index=t)
    return pd.DataFrame(X, index=t), y, groups


def test_fuzzy_selector_finds_exactly_the_thermal_groups():
    X, y, groups = _grouped_recording()
    sel = FuzzySensitivity(random_state=0).fit(X, y)
    found = {}
    for name, cls in sel.classes_.items():
        found.setdefault(cls, set()).add(name)
    expected = {}
    for name, g in groups.items():
        expected.setdefault(g, set()).add(name)
    assert sorted(map(sorted, found.values())) == sorted(map(sorted, expected.values()))
    assert len(sel.selected_) == 3 and {groups[c] for c in sel.selected_} == {0, 1, 2}
    f = sel.report_["fuzzy_f_by_lambda"]
    assert f.loc[f["F"].idxmax(), "classes"] == 3


def test_transitive_closure_is_max_min_transitive():
    rng = np.random.default_rng(1)
    X = pd.DataFrame(rng.normal(size=(200, 9)).cumsum(axis=0))
    r = similarity(X)
    closure = transitive_closure(r)
    assert np.all(closure >= r - 1e-15)  # the closure contains R
    assert np.allclose(max_min(closure, closure), closure)  # t(R)∘t(R) = t(R): max-min transitive
    assert np.all(closure >= np.minimum(closure[:, :, None], closure[None, :, :]).max(axis=1) - 1e-15)
    # every lambda-cut of the closure is an equivalence relation: classes are cliques of {t(R) >= lambda}
    for lam in np.unique(closure):
        labels = lambda_cut(closure, lam)
        same = labels[:, None] == labels[None, :]
        assert np.array_equal(same, closure >= lam - 1e-12)


def test_gra_keeps_the_related_sensors_and_one_per_group():
    X, _, groups = _grouped_recording(seed=2)
    y = pd.DataFrame({"disp_um": sum(X[f"T{k}0"] - 20 for k in range(3))}, index=X.index)  # all heat adds drift
    noise = np.random.default_rng(3).normal(size=(len(X), 2)).cumsum(axis=0)
    X = X.assign(T_noise_a=20 + noise[:, 0], T_noise_b=20 + noise[:, 1])
    grades = grey_grades(X.to_numpy(), y.to_numpy())
    assert grades.min() > 0 and grades.max() <= 1
    sel = GRAHierarchical(top_m=9, n_groups=3).fit(X, y)
    assert sel.report_["gra_grades"].set_index("sensor")["kept"].sum() == 9
    assert set(sel.groups_) == set(groups)  # the unrelated sensors have the lowest grades
    assert len(sel.selected_) == 3
    assert {groups.get(c) for c in sel.selected_} == {0, 1, 2}
    path = sel.report_["gra_selection_path"]
    assert list(path["sensor"]) and set(path["sensor"]) == set(sel.selected_)


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
