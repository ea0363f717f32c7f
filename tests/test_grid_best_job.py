"""A grid's best job is chosen within one protocol (honest first, paper jobs labelled), and the grid table tells
two configurations of one split kind apart (S1's 360/60 and 80/20 paper splits)."""

from types import SimpleNamespace

import mlflow
import pytest
from mlflow.tracking import MlflowClient
from omegaconf import OmegaConf

from thermodrift.core import report, tracking


def _run(run_id, protocol, valid, model="lstm", reference=False, status="FINISHED"):
    tags = {"protocol": protocol, "model": model, **({"reference": "reads the measured target"} if reference else {})}
    return SimpleNamespace(info=SimpleNamespace(run_id=run_id, run_name=run_id, status=status),
                           data=SimpleNamespace(tags=tags, metrics={"valid/best_rmse": valid}, params={}))


def test_the_best_job_is_chosen_within_a_protocol_honest_first():
    runs = [_run("paper_a", "paper", 0.4), _run("honest_a", "honest", 2.0), _run("honest_b", "honest", 1.5),
            _run("paper_b", "paper", 0.6), _run("persistence", "honest", 0.1, "persistence", reference=True),
            _run("failed", "honest", 0.01, status="FAILED")]
    assert [r.info.run_id for r in report.best_jobs(runs)] == ["honest_b", "paper_a"]


def test_a_grid_of_paper_jobs_only_has_a_labelled_paper_best():
    best = report.best_jobs([_run("p1", "paper", 1.0), _run("p2", "paper", 0.5)])
    assert [r.info.run_id for r in best] == ["p2"]
    (line,) = report.best_job_lines(best)
    assert line.startswith("best paper job by inner validation RMSE (protocol=paper") and line.endswith("p2 (p2)")


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    """A sweep's parent run and four finished job runs in a SQLite MLflow store: two honest jobs and one job on each
    of S1's two paper splits, the paper jobs with the lowest validation RMSEs."""
    uri = f"sqlite:///{tmp_path_factory.mktemp('grid') / 'mlflow.db'}"
    exp = tracking.setup(uri, "grid")
    client = MlflowClient()
    parent = client.create_run(exp, run_name="sweep", tags={"kind": "sweep"}).info.run_id
    splits = {"paper_360": ("paper_session", {"train": 360, "test": 60}, 0.3),
              "paper_336": ("paper_session", {"train": 336, "test": 84}, 0.2),
              "honest_lstm": ("condition_holdout", {"train_on": "before"}, 2.0),
              "honest_mlr": ("condition_holdout", {"train_on": "before"}, 2.5)}
    ids = {}
    for name, (kind, params, valid) in splits.items():
        protocol = "paper" if kind == "paper_session" else "honest"
        run = client.create_run(exp, run_name=name, tags={
            "mlflow.parentRunId": parent, "dataset": "turning_centre_s1", "selector": "all",
            "model": name.split("_")[-1] if protocol == "honest" else "lstm", "optimizer": "pso", "split": kind,
            "protocol": protocol, "ablation": "none", "targets": "radial_error"})
        for k, v in params.items():
            client.log_param(run.info.run_id, f"split.params.{k}", v)
        metrics = {"valid/best_rmse": valid, "test/rmse": valid + 1, "test/radial_error/rmse": valid + 1}
        for metric, value in metrics.items():
            client.log_metric(run.info.run_id, metric, value)
        client.set_terminated(run.info.run_id)
        ids[name] = run.info.run_id
    return uri, client, parent, ids


def test_the_parent_carries_the_best_honest_job_and_names_the_best_paper_job(grid, capsys, monkeypatch):
    uri, client, parent, ids = grid
    monkeypatch.setenv(tracking.PARENT_ENV, parent)
    tracking.SweepRun().on_multirun_end(OmegaConf.create({"tracking": {"uri": uri, "experiment": "grid"}}))
    tags = client.get_run(parent).data.tags
    assert tags["best_run_id"] == ids["honest_lstm"] and tags["best_protocol"] == "honest"
    assert tags["best_paper_run_id"] == ids["paper_336"]
    assert client.get_run(parent).data.metrics["valid/best_rmse"] == 2.0  # the honest job's, not a paper one's
    out = capsys.readouterr().out
    assert f"best job by inner validation RMSE: honest_lstm ({ids['honest_lstm']})" in out
    assert "best paper job by inner validation RMSE (protocol=paper" in out
    assert f"paper_336 ({ids['paper_336']})" in out


def test_the_grid_table_labels_the_two_paper_splits_distinctly(grid):
    uri, client, parent, ids = grid
    mlflow.set_tracking_uri(uri)
    children = [client.get_run(i) for i in ids.values()]
    table = report.runs_table(children)
    assert list(table["split"]) == ["paper_session (test=60, train=360)", "paper_session (test=84, train=336)",
                                    "condition_holdout", "condition_holdout"]
    assert list(table["protocol"]) == ["paper", "paper", "honest", "honest"]
