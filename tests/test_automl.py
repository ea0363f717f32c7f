"""``thermodrift automl``: determinism, leak-free inner folds, plugins in the leaderboard, failures recorded, bad
input, the pipeline and ensemble models (streaming, storing), and the verb end to end in MLflow."""

from __future__ import annotations

import json

import mlflow
import numpy as np
import pandas as pd
import pytest

from thermodrift.core import artifacts, efficiency, registry, splits
from thermodrift.core.automl import folds as inner, job, leaderboard, space
from thermodrift.core.automl.evaluate import Evaluator
from thermodrift.core.automl.search import Settings
from thermodrift.core.components import ThermalModel
from thermodrift.core.study import JobSpec, model_inputs
from thermodrift.testing.data import tiny_recording

FEATURES = {"taus_s": [600.0, 3000.0], "powers": [1.0, 2.0]}


def _spec(**kw) -> JobSpec:
    return JobSpec(dataset="recording_file", model="mlr", storage=None, progress=False, seed=0, **kw)


def _run(families, budget=10, **kw):
    return job.run(_spec(), Settings(budget_fits=budget, families=families, max_folds=2, **kw),
                   recording=tiny_recording())


def test_same_seed_and_budget_give_the_same_leaderboard():
    boards = [_run(["mlr", "ridge_demo", "transfer_function"], budget=14).leaderboard for _ in range(2)]
    keep = [c for c in boards[0].columns if c not in leaderboard.TIMING]
    pd.testing.assert_frame_equal(boards[0][keep], boards[1][keep])
    assert len(boards[0]) >= 5 and (boards[0]["status"] == "ok").all()
    assert {"fold1_rmse", "inner_score", "fit_s", "latency_batch_ms", "latency_stream_ms", "n_parameters"} \
        <= set(boards[0].columns)
    # a row's settings name what sets it apart: a portfolio row on the penalty path shows its alpha, a default row none
    rows = boards[0].set_index("trial")
    for trial, r in rows[rows["model"] != "ensemble"].iterrows():
        params = json.loads(r["params"])["model_params"]
        assert r["settings"] == ", ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
                                          for k, v in params.items() if k != "trainer")
    assert (rows["settings"] == "").any() and rows["settings"].str.startswith("alpha=").any()


def test_every_registered_model_takes_part_and_a_plugin_appears_in_the_leaderboard():
    names = {f.name for f in space.families()}
    assert {"ridge_demo", "mlr", "lptn_hybrid", "transfer_function", "lstm"} <= names
    assert "persistence" not in names and "pipeline" not in names  # a reference; the search's own output
    board = _run(["ridge_demo", "mlr"], budget=10).leaderboard
    assert "ridge_demo" in set(board["model"])


def test_inner_folds_chain_forward_inside_the_training_part():
    rec = tiny_recording()
    for split in (splits.ConditionHoldout(), splits.ConditionHoldout(test_conditions=["4000"], train_on="others")):
        (outer,) = split.folds(rec)
        folds = inner.inner_folds(rec, outer.train)
        assert len(folds) >= 2
        for f in folds:
            assert set(f.train) <= set(outer.train) and set(f.test) <= set(outer.train)
            assert f.train.max() < f.test.min()  # nothing of a fold's future informs it
            assert not set(outer.test) & (set(f.train) | set(f.test))


def test_held_out_rows_cannot_change_the_search():
    """Scores on the inner folds stay the same when the outer held-out rows (inputs and targets) are replaced."""
    rec = tiny_recording()
    (outer,) = splits.ConditionHoldout(test_conditions=["4000"], train_on="others").folds(rec)
    folds = inner.inner_folds(rec, outer.train)
    params = {"model": "mlr", "features": FEATURES}
    first = Evaluator(rec, outer.train, ["disp_z_um", "disp_x_um"], folds).evaluate(params, measure_costs=False)
    spoiled = tiny_recording()
    spoiled.data = spoiled.data.copy()
    cols = [c for c in spoiled.data.columns if c != "speed_rpm"]
    spoiled.data.iloc[outer.test, [spoiled.data.columns.get_loc(c) for c in cols]] = 1e6
    second = Evaluator(spoiled, outer.train, ["disp_z_um", "disp_x_um"], folds).evaluate(params,
                                                                                          measure_costs=False)
    assert first.fold_rmse == second.fold_rmse


class Broken(ThermalModel):
    """A family whose every fit fails."""

    def _fit(self, X, y):
        raise RuntimeError("this family cannot fit")


@pytest.fixture()
def broken_family():
    reg = registry.default()
    reg.add("model", "broken_family", Broken)
    yield
    del reg.components["model"]["broken_family"]


def test_a_failing_family_is_one_line_and_a_failed_row_and_the_search_goes_on(broken_family):
    said = []
    result = job.run(_spec(), Settings(budget_fits=10, families=["broken_family", "mlr"], max_folds=2),
                     say=said.append, recording=tiny_recording())
    board = result.leaderboard
    failed = board[board["status"] == "failed"]
    assert list(failed["model"]) == ["broken_family"] and "cannot fit" in failed["error"].iloc[0]
    assert (board[board["model"] == "mlr"]["status"] == "ok").sum() >= 3
    assert len([s for s in said if "broken_family" in s]) == 1
    assert result.job.model is not None and result.job.spec.model in ("pipeline", "ensemble")


def test_pipeline_streams_exactly_and_round_trips_with_a_plugin_inside(tmp_path):
    rec = tiny_recording()
    targets = ["disp_z_um", "disp_x_um"]
    X = model_inputs(rec, rec.columns("temperature") + rec.columns("ambient"),
                     registry.get("model", "pipeline").factory, targets)
    y = rec.data[targets]
    for params in ({"model": "ridge_demo", "features": FEATURES, "selector": "correlation_top_k",
                    "selector_params": {"k": 2}},
                   {"model": "lstm", "model_params": {"hidden_units": 3, "trainer": {"epochs": 3, "t0": 1}},
                    "features": FEATURES},
                   {"model": "transfer_function"}):
        model = registry.create("model", "pipeline", **params).fit(X.iloc[:200], y.iloc[:200])
        batch = model.predict(X.iloc[200:], history=X.iloc[:200])
        stream = model.streamer(X.iloc[:200])
        streamed = np.array([stream.update(X.iloc[i]) for i in range(200, 260)])
        assert np.abs(streamed - batch[:60]).max() < 1e-6, params["model"]
        artifacts.save(model, "pipeline", tmp_path / params["model"])
        back = artifacts.load(tmp_path / params["model"])
        assert np.allclose(back.predict(X.iloc[200:], history=X.iloc[:200]), batch, atol=1e-9)


def test_ensemble_streams_and_exports_its_members():
    rec = tiny_recording()
    targets = ["disp_z_um"]
    X = model_inputs(rec, rec.columns("temperature"), registry.get("model", "ensemble").factory, targets)
    model = registry.create("model", "ensemble", members=[{"model": "ridge_demo"},
                                                          {"model": "mlr", "features": FEATURES}],
                            weights=[1, 3]).fit(X.iloc[:200], rec.data[targets].iloc[:200])
    batch = model.predict(X.iloc[200:], history=X.iloc[:200])
    stream = model.streamer(X.iloc[:200])
    streamed = np.array([stream.update(X.iloc[i]) for i in range(200, 250)])
    assert np.abs(streamed - batch[:50]).max() < 1e-9
    assert model.weights_.tolist() == [0.25, 0.75] and model.history_length is None
    assert efficiency.parameter_count(model) == sum(efficiency.parameter_count(m) for m in model.members_) > 0


def test_exported_pipeline_and_ensemble_stream_as_the_compensator_runs_them():
    """``export_state()`` follows the export contract: the compensator's runtimes reproduce ``predict``."""
    from thermodrift.compensator import runtime

    rec = tiny_recording()
    targets = ["disp_z_um", "disp_x_um"]
    X = model_inputs(rec, rec.columns("temperature"), registry.get("model", "pipeline").factory, targets)
    y = rec.data[targets]
    models = [registry.create("model", "pipeline", model="mlr", features=FEATURES, selector="correlation_top_k",
                              selector_params={"k": 2}),
              registry.create("model", "ensemble", members=[{"model": "transfer_function"},
                                                            {"model": "mlr", "features": FEATURES}], weights=[1, 2])]
    for model in models:
        state = model.fit(X.iloc[:200], y.iloc[:200]).export_state()
        assert state["inputs"] == list(X.columns) and state["targets"] == targets
        if state["runtime"] == "pipeline":
            assert len(state["selected"]) == 3 and "speed_rpm" in state["selected"]  # 2 sensors + the drive
            assert state["model"]["inputs"] == state["features"]["names"]
        rt = runtime.build(state)
        stream = rt.streamer(X.iloc[:200].to_numpy(dtype=float), X.index[:200].to_numpy(dtype=float))
        out = np.array([stream.update(X.iloc[i].to_numpy(dtype=float), float(X.index[i])) for i in range(200, 240)])
        assert np.abs(out - model.predict(X.iloc[200:240], history=X.iloc[:200])).max() < 1e-9


TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false"]


def test_bad_input_is_one_line_and_exit_2(tmp_path, cli):
    tiny_recording().write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    typo = cli(tmp_path, "automl", *TINY, "automl.budget_fit=3")
    assert typo.returncode == 2 and "did you mean 'automl.budget_fits'" in typo.stderr
    unknown = cli(tmp_path, "automl", *TINY, "automl.families=[no_such_model]")
    lines = [ln for ln in unknown.stderr.splitlines() if ln.strip()]
    assert unknown.returncode == 2 and len(lines) == 1 and "no_such_model" in lines[0], unknown.stderr
    assert "Traceback" not in typo.stderr + unknown.stderr
    helped = cli(tmp_path, "automl", "--help")
    assert helped.returncode == 0 and "budget_fits" in helped.stdout


def test_verb_logs_a_parent_run_with_leaderboard_and_family_children(tmp_path, cli):
    tiny_recording().write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    out = cli(tmp_path, "automl", *TINY, "automl.budget_fits=8", "automl.max_folds=2",
              "automl.families=[mlr,ridge_demo]")
    assert out.returncode == 0, out.stderr[-2000:]
    mlflow.set_tracking_uri(f"sqlite:///{tmp_path / 'mlflow.db'}")
    runs = mlflow.search_runs(experiment_names=["thermodrift"], output_format="list")
    (parent,) = [r for r in runs if r.data.tags.get("kind") == "automl"]
    children = [r for r in runs if r.data.tags.get("kind") == "automl_candidate"]
    assert {c.data.tags["model"] for c in children} == {"mlr", "ridge_demo"}
    assert all(c.data.tags["mlflow.parentRunId"] == parent.info.run_id for c in children)
    assert {"test/rmse", "baseline/persistence/test/rmse", "baseline/mlr/test/rmse"} <= set(parent.data.metrics)
    client = mlflow.MlflowClient()
    names = {a.path for a in client.list_artifacts(parent.info.run_id)}
    assert {"leaderboard.csv", "leaderboard.md", "limits.json"} <= names
    board = pd.read_csv(client.download_artifacts(parent.info.run_id, "leaderboard.csv", str(tmp_path)))
    assert set(board["model"]) <= {"mlr", "ridge_demo", "ensemble"}
    assert out.stdout.strip().splitlines()[-1].startswith(f"MLflow run {parent.info.run_id} at ")
    model = mlflow.pyfunc.load_model(f"runs:/{parent.info.run_id}/model")
    assert model is not None


def test_a_rerun_resumes_from_the_storage_and_only_runs_the_missing_budget(tmp_path):
    spec = JobSpec(dataset="recording_file", model="mlr", storage=f"sqlite:///{tmp_path / 'o.db'}", progress=False)
    said = []
    first = job.run(spec, Settings(budget_fits=6, families=["mlr", "ridge_demo"], max_folds=2),
                    recording=tiny_recording())
    second = job.run(spec, Settings(budget_fits=10, families=["mlr", "ridge_demo"], max_folds=2),
                     say=said.append, recording=tiny_recording())
    assert first.search.fits == 6 and second.search.fits == 10 and any("resumed" in s for s in said)
    assert [e.number for e in second.search.entries][:3] == [e.number for e in first.search.entries]
    assert [e.score for e in second.search.entries][:3] == [e.score for e in first.search.entries]


def test_portfolio_reads_each_filter_bank_along_the_penalty_path_cheap_families_untuned_first():
    fams = space.families(only=["mlr", "transfer_function", "lptn"])
    cands = space.portfolio(fams, {"all": {}})
    mlr_feats = [c for c in cands if c.family == "mlr" and c.params["features"]]
    alpha_high = space.families(only=["mlr"])[0].space["alpha"]["high"]
    expected = {(tuple(b["taus_s"]), min(a, alpha_high)) for b in space.FILTER_BANKS for a in space.ALPHA_PATH}
    assert {(tuple(c.params["features"]["taus_s"]), c.params["model_params"]["alpha"]) for c in mlr_feats} == expected
    assert not [c for c in cands if c.family in ("transfer_function", "lptn") and c.params["features"]]
    order = [(c.family, bool(c.params["features"])) for c in cands]
    # every cheap family's untuned pipeline comes before the first feature pipeline, and the physics family last
    assert order.index(("transfer_function", False)) < order.index(("mlr", True))
    assert order[-1] == ("lptn", False)


def test_networks_are_promoted_before_tpe_spends_the_budget(monkeypatch):
    from thermodrift.core.automl import search

    monkeypatch.setattr(search, "PROMOTE_WITHIN", float("inf"))  # every network is worth more epochs here
    board = _run(["mlr", "bp"], budget=40, top_rung=1).leaderboard
    assert "rung1" in set(board["phase"]) and "tpe" in set(board["phase"])
    assert board.loc[board["phase"] == "rung1", "trial"].max() < board.loc[board["phase"] == "tpe", "trial"].min()


def test_lptn_and_lptn_hybrid_on_the_same_rows_share_one_calibration(monkeypatch):
    """AutoML fits both physics families on every inner fold: the deterministic calibration runs once, and a
    model built from the shared result predicts exactly as one calibrated alone."""
    from thermodrift.core.physics import calibration as cal
    from thermodrift.plugins.models import lptn

    rec = tiny_recording()
    targets = ["disp_z_um"]
    X = model_inputs(rec, rec.columns("temperature"), registry.get("model", "lptn").factory, targets)
    y = rec.data[targets]
    small = {"hidden_nodes": 1, "max_evaluations": 5, "max_fit_samples": 150}
    alone = registry.create("model", "lptn", **small).fit(X.iloc[:200], y.iloc[:200]).predict(X.iloc[200:260])
    calls = []
    real = cal.calibrate
    monkeypatch.setattr(cal, "calibrate", lambda *a, **k: calls.append(1) or real(*a, **k))
    monkeypatch.setattr(lptn, "_CALIBRATIONS", {})
    first = registry.create("model", "lptn", **small).fit(X.iloc[:200], y.iloc[:200])
    registry.create("model", "lptn_hybrid", **small, alpha=1.0).fit(X.iloc[:200], y.iloc[:200])
    registry.create("model", "lptn", **small).fit(X.iloc[:150], y.iloc[:150])  # other rows: calibrated anew
    assert len(calls) == 2
    np.testing.assert_array_equal(first.predict(X.iloc[200:260]), alone)


def test_an_ensemble_whose_members_cancel_only_on_the_inner_folds_loses_out_of_fold():
    from thermodrift.core.automl.ensemble import caruana, out_of_fold

    n = 50
    truth = [np.zeros((n, 1)), np.zeros((n, 1))]

    def fold_rmse(pred, k):
        return float(np.sqrt(np.mean((pred - truth[k]) ** 2)))

    def score(mix):
        return inner.aggregate([fold_rmse(m, k) for k, m in enumerate(mix)])

    const = [[np.full((n, 1), a), np.full((n, 1), b)] for a, b in ((1.0, 1.0), (-0.9, 0.5))]
    weights, in_sample = caruana(const, score)
    assert in_sample < min(score(p) for p in const)  # in sample, the cancelling pair wins
    ens, single = out_of_fold(const, fold_rmse, inner.aggregate)
    assert ens > single  # out of fold it does not
    rng = np.random.default_rng(0)
    noisy = [[rng.normal(0.0, 1.0, (n, 1)) for _ in range(2)] for _ in range(3)]
    ens, single = out_of_fold(noisy, fold_rmse, inner.aggregate)
    assert ens < single  # independent errors: averaging wins out of fold too


def test_a_tuned_candidate_enters_the_final_choice_only_when_it_beats_the_a_priori_best_by_one_se():
    import optuna

    from thermodrift.core.automl.evaluate import Evaluation
    from thermodrift.core.automl.search import Entry, Search, earns_its_place

    assert earns_its_place([0.9, 0.8], [1.0, 1.0])
    assert not earns_its_place([0.5, 1.05], [1.0, 1.0])  # two folds: better on both, not on average
    assert earns_its_place([0.90, 0.95, 0.92], [1.0, 1.0, 1.0])
    assert not earns_its_place([0.2, 1.1, 1.2], [1.0, 1.0, 1.0])  # a mean gain within the fold noise
    assert not earns_its_place([np.nan, 0.1], [1.0, 1.0])
    assert not earns_its_place([0.5], [1.0])  # one fold: no noise estimate, so no gain is shown

    rec = tiny_recording()
    (outer,) = splits.ConditionHoldout(test_conditions=["4000"], train_on="others").folds(rec)
    ev = Evaluator(rec, outer.train, ["disp_z_um"], inner.inner_folds(rec, outer.train, 2))
    said = []
    search = Search(ev, optuna.create_study(), Settings(families=["mlr"]), said.append, progress=False)

    def entry(number, phase, fold_rmse):
        cand = space.Candidate({"model": "mlr", "model_params": {}, "selector": "all", "selector_params": {},
                                "features": None})
        return Entry(number, cand, Evaluation(fold_rmse, {}, inner.aggregate(fold_rmse)), phase=phase)

    prior, lucky, steady = entry(0, "portfolio", [1.0, 1.0]), entry(1, "tpe", [0.5, 1.05]), entry(2, "tpe", [0.9, 0.95])
    assert lucky.score < steady.score < prior.score
    eligible = search._eligible([prior, lucky, steady])
    assert [e.number for e in eligible] == [0, 2]
    assert search._best(eligible) is steady
    assert said and "1 TPE candidate" in said[0]
    assert "do not beat trial 0 (" in said[0] and "#" not in said[0]  # numbered as the leaderboard shows it


def test_the_candidates_the_folds_cannot_tell_from_the_best_are_averaged_by_inverse_mean_squared_fold_rmse():
    import optuna

    from thermodrift.core.automl.evaluate import Evaluation
    from thermodrift.core.automl.search import Entry, Search

    rec = tiny_recording()
    (outer,) = splits.ConditionHoldout(test_conditions=["4000"], train_on="others").folds(rec)

    def search_on(n_folds):
        ev = Evaluator(rec, outer.train, ["disp_z_um"], inner.inner_folds(rec, outer.train, n_folds))
        assert len(ev.folds) == n_folds
        return ev, Search(ev, optuna.create_study(), Settings(families=["mlr"]), progress=False)

    def entry(ev, number, offsets):  # predictions off the truth by a constant per fold: RMSE = |offset| (µm)
        preds = [t.to_numpy() + c for t, c in zip(ev.truth, offsets)]
        rmse, score = ev.score_predictions(preds)
        cand = space.Candidate({"model": "mlr", "model_params": {"alpha": float(number)}, "selector": "all",
                                "selector_params": {}, "features": None}, origin="portfolio")
        return Entry(number, cand, Evaluation(rmse, {}, score, preds), phase="portfolio")

    ev, search = search_on(2)
    best, close, twin, far = (entry(ev, 0, [1.0, 1.0]), entry(ev, 1, [-1.1, -0.95]), entry(ev, 2, [1.0, 1.0]),
                              entry(ev, 3, [3.0, 3.0]))
    hedge = search._hedge([far, close, twin, best], best)
    assert hedge["numbers"] == [0, 1]  # the twin predicts as the best does and counts once; far is beaten
    w = np.array([1.0, 1.0 / np.mean(np.square([1.1, 0.95]))])
    w /= w.sum()
    np.testing.assert_allclose(hedge["weights"], w)  # the best's fold errors are smaller: it weighs more
    assert hedge["weights"][0] > hedge["weights"][1]
    np.testing.assert_allclose(hedge["fold_rmse"], [abs(w[0] - 1.1 * w[1]), abs(w[0] - 0.95 * w[1])],
                               atol=1e-9)  # their errors partly cancel
    assert [m["model_params"]["alpha"] for m in hedge["members"]] == [0.0, 1.0]
    swinging = entry(ev, 5, [-0.2, -2.2])  # kept in by its wide standard error, but its fold errors swing
    swung = search._hedge([best, swinging], best)
    assert swung["numbers"] == [0, 5] and swung["weights"][1] < 0.5 * swung["weights"][0]
    assert search._hedge([best, twin, far], best) is None  # nothing but the best itself
    tuned = [entry(ev, 4 + i, [1.0 + 0.01 * i, -1.0]) for i in range(3)]  # near-copies from one family's TPE
    for e in tuned:
        e.phase = "tpe"
    assert search._hedge([best, close] + tuned, best)["numbers"] == [0, 4, 1]  # its best one alone takes part

    ev1, search1 = search_on(1)
    assert search1._hedge([entry(ev1, 0, [1.0]), entry(ev1, 1, [-1.0])], entry(ev1, 0, [1.0])) is None


def test_inverse_mse_weights_favour_the_steadier_member_and_survive_a_perfect_one():
    from thermodrift.core.automl.evaluate import Evaluation
    from thermodrift.core.automl.search import Entry, inverse_mse_weights

    def entry(fold_rmse):
        return Entry(0, space.Candidate({"model": "mlr"}), Evaluation(fold_rmse, {}, max(fold_rmse)))

    w = inverse_mse_weights([entry([1.0, 1.0]), entry([0.0, 2.0])])  # mean squared fold RMSE 1 and 2
    np.testing.assert_allclose(w, [2 / 3, 1 / 3])
    assert inverse_mse_weights([entry([0.0, 0.0]), entry([1.0, 1.0]), entry([0.0, 0.0])]) == [0.5, 0.0, 0.5]
