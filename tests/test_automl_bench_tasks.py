"""The AutoML benchmark's tasks on the independent generators' machines (benchmarks/bench_automl.py): the recording
goes through the public file format, and the held-out working condition is long enough to score on."""

from pathlib import Path

import numpy as np

from thermodrift.core import registry, splits
from thermodrift.core.automl import folds as inner

from support import load_file

BENCH = Path(__file__).resolve().parent.parent / "benchmarks" / "bench_automl.py"
VARIANTS = BENCH.parent / "bench_automl_variants.py"


def test_independent_task_holds_out_the_last_condition_long_enough_to_score(tmp_path):
    bench = load_file(BENCH)
    # fd seed 1 ends with a short speed step (under 5 % of the rows): the condition before it is held out
    spec = bench.spec_of(bench.TASKS["fd_coolant_coupling_1"], 0, None, tmp_path)
    assert spec.dataset == "recording_file" and Path(spec.dataset_params["table"]).is_file()
    rec = registry.create("dataset", spec.dataset, **spec.dataset_params)
    labels = rec.conditions().to_numpy()
    order = list(dict.fromkeys(labels))
    (held,) = spec.split_params["test_conditions"]
    assert np.count_nonzero(labels == order[-1]) < inner.MIN_SHARE * len(labels)
    assert held == order[-2]
    (fold,) = splits.make_split(spec.split, **spec.split_params).folds(rec)
    assert set(labels[fold.test]) == {held} and fold.train.max() < fold.test.min()
    assert len(inner.inner_folds(rec, fold.train)) >= 2
    # a recording whose last condition is long enough keeps the default: the last condition held out
    spec = bench.spec_of(bench.TASKS["fd_null_500"], 0, None, tmp_path)
    labels = registry.create("dataset", spec.dataset, **spec.dataset_params).conditions().to_numpy()
    assert spec.split_params["test_conditions"] == [list(dict.fromkeys(labels))[-1]]


def test_indep_group_names_every_independent_task():
    bench = load_file(BENCH)
    assert bench.GROUPS["indep"] and all("generator" in bench.TASKS[n] for n in bench.GROUPS["indep"])
    assert {bench.TASKS[n]["generator"] for n in bench.GROUPS["indep"]} == {"fd", "lumped"}
    assert all(bench.TASKS[n]["case_seed"] < 1000 for n in bench.GROUPS["indep"])  # development seeds only
    sealed = bench.GROUPS["indep_sealed"]
    assert len(sealed) == len(bench.GROUPS["indep"]) and not set(sealed) & set(bench.GROUPS["indep"])
    assert all(bench.TASKS[n]["case_seed"] >= 1000 for n in sealed)  # the sealed half of the generators' seeds
    assert {bench.TASKS[n]["generator"] for n in sealed} == {"fd", "lumped"}
    assert sum(bench.TASKS[n]["hidden"] is None for n in sealed) == 8  # four nulls per generator
    second = bench.GROUPS["indep_sealed2"]
    assert len(second) == len(sealed) and not set(second) & (set(sealed) | set(bench.GROUPS["indep"]))
    assert all(bench.TASKS[n]["case_seed"] >= 10000 for n in second)
    assert sum(bench.TASKS[n]["hidden"] is None for n in second) == 8
    # between the two sealed sets each generator meets eight planted mechanisms, no mechanism twice on one
    for g in ("fd", "lumped"):
        planted = [bench.TASKS[n]["hidden"] for n in sealed + second
                   if bench.TASKS[n]["generator"] == g and bench.TASKS[n]["hidden"]]
        assert len(planted) == 8 and len(set(planted)) == 8


def _cand(phase, fold_rmse, fold_pred, pred, model="mlr", features=None):
    from thermodrift.core.automl.folds import aggregate
    return {"label": model, "params": {"model": model, "features": features}, "phase": phase, "fold_rmse": fold_rmse,
            "score": aggregate(fold_rmse), "fold_pred": [np.full((2, 1), v) for v in fold_pred],
            "pred": np.full((2, 1), pred)}


def test_final_rules_replay_the_search_rules():
    bench = load_file(BENCH)
    # fold truth 0 on three folds; a candidate predicting the constant v has fold RMSE |v|
    a = _cand("portfolio", [1.0, 1.0, 1.0], [1.0, 1.0, 1.0], 2.0)                      # best a-priori
    b = _cand("portfolio", [1.1, 0.9, 1.05], [1.1, -0.9, 1.05], -1.0, model="lptn")     # not separable from a
    c = _cand("portfolio", [3.0, 3.0, 3.0], [3.0, 3.0, 3.0], 0.0)                      # clearly worse
    d = _cand("tpe", [0.95, 1.2, 0.9], [0.95, 1.2, 0.9], 0.0)                          # does not earn its place
    saved = {"fold_truth": [np.zeros((2, 1))] * 3, "truth": np.zeros((2, 1)), "candidates": [a, b, c, d]}
    r = bench.final_rules(saved)
    assert r["best single"] == (2.0, 1)
    assert r["one-SE flat"] == (0.5, 2)  # (2.0 - 1.0) / 2: a and b averaged; c beaten, d not eligible (the rule before)
    assert r["hindsight best candidate"] == (0.0, 1)
    w = np.array([1.0, 1.0 / np.mean(np.square([1.1, 0.9, 1.05]))])  # inverse mean squared fold RMSE of a and b
    held, members = r["one-SE inverse-MSE weights"]  # the search's rule
    assert members == 2 and np.isclose(held, abs(2.0 * w[0] - 1.0 * w[1]) / w.sum()) and held > 0.5  # b weighs less


def test_rule_variants_replay_swaps_one_piece_and_restores_the_library():
    variants = load_file(VARIANTS)
    from thermodrift.core.automl import folds, search
    aggregate, earns = folds.aggregate, search.earns_its_place
    a = _cand("portfolio", [1.0, 1.0, 1.0], [1.0, 1.0, 1.0], 2.0)    # best a-priori
    c = _cand("portfolio", [3.0, 3.0, 3.0], [3.0, 3.0, 3.0], 0.5)    # clearly worse
    t = _cand("tpe", [0.5, 0.5, 0.5], [0.5, 0.5, 0.5], 1.0)          # tuned, better on every fold: earns its place
    saved = {"fold_truth": [np.zeros((2, 1))] * 3, "truth": np.zeros((2, 1)), "candidates": [a, c, t]}
    r = variants.replay(saved, [100, 200, 300])
    assert r["search's rule"] == load_file(BENCH).final_rules(saved)["one-SE inverse-MSE weights"][0] == 1.0  # t chosen
    assert r["a-priori only"] == 2.0  # without the tuned candidate, a is the choice
    assert saved["candidates"][2]["phase"] == "tpe" and saved["candidates"][0]["score"] == aggregate([1.0] * 3)
    assert folds.aggregate is aggregate and search.earns_its_place is earns  # the patches are undone
    # the size-weighted score weighs the later folds more: [4, 1, 1] over sizes 1:1:2 gives 1.75, not (2 + 4) / 2
    scores = {}
    for label, patches in variants.variants([100, 100, 200]).items():
        with variants._patched(patches):
            scores[label] = folds.aggregate([4.0, 1.0, 1.0])
    assert scores["size-weighted mean"] == 1.75 and scores["search's rule"] == 3.0 and scores["mean"] == 2.0
    assert scores["(mean + last) / 2"] == 1.5 and np.isclose(scores["log SE + geometric mean"], 4 ** (1 / 3))


def test_larger_portfolios_of_the_variants_replay():
    variants = load_file(VARIANTS)
    extra = variants.portfolio_variants()
    penalty = {(c.params["model"], c.params["model_params"]["alpha"])
               for c in extra["penalty path without a feature stage"]}
    assert penalty == {("lptn_hybrid", 1.0), ("lptn_hybrid", 100.0), ("mnr", 10.0), ("mnr", 100.0)}  # defaults: 10, 1
    ends = {(c.params["model"], c.params["model_params"]["hidden_nodes"])
            for c in extra["medium families' integer ends"]}
    assert ends == {("lptn", 0), ("lptn", 4), ("lptn_hybrid", 0), ("lptn_hybrid", 4)}  # default 2
    assert all(c.params["features"] is None and c.params["selector"] == "all" for v in extra.values() for c in v)
