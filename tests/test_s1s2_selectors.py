"""S1's fuzzy-sensitivity and S2's grey-relational selectors on recordings whose answer is known."""

import numpy as np
import pandas as pd

from thermodrift.plugins.selectors.fuzzy_sensitivity import (FuzzySensitivity, lambda_cut, max_min, similarity,
                                                              transitive_closure)
from thermodrift.plugins.selectors.gra_hierarchical import GRAHierarchical, grey_grades


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
