"""`thermodrift report` regenerates the studies' tables from a small real sweep in MLflow."""

import os
import subprocess
import sys

import mlflow
import pandas as pd

from thermodrift.testing.data import tiny_recording

EXE = [sys.executable, "-m", "thermodrift.core.cli"]
TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false"]


def _cli(cwd, *args):
    env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true"}
    env.pop("THERMODRIFT_SWEEP_ID", None)
    return subprocess.run([*EXE, *args], cwd=cwd, capture_output=True, text=True, timeout=600, env=env)


def test_report_regenerates_tables_from_a_sweep(tmp_path):
    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    out = _cli(tmp_path, "run", "-m", *TINY, "model=mlr,mnr", "split=chronological,shuffled", "n_trials=2",
               "selector=all")
    assert out.returncode == 0, out.stderr[-2000:]
    (sweep,) = [p.name for p in (tmp_path / "multirun").iterdir()]
    rep = _cli(tmp_path, "report", sweep)
    assert rep.returncode == 0, rep.stderr[-2000:]
    assert "S1 Table 7 analogue" in rep.stdout and "S2 analogue" in rep.stdout
    table = pd.read_csv(tmp_path / "reports" / sweep / "s1_table7.csv")
    assert set(table["protocol"]) == {"paper", "honest"}
    assert {"mlr (tpe)", "mnr (tpe)", "persistence", "mlr"} <= set(table["source"])
    assert len(table) == 2 * 4  # per split: the two tuned models and the two baselines (same in both jobs)
    mlflow.set_tracking_uri(f"sqlite:///{tmp_path / 'mlflow.db'}")
    runs = mlflow.search_runs(experiment_names=["thermodrift"], output_format="list")
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    for run in (r for r in runs if r.data.tags.get("mlflow.parentRunId") == parent.info.run_id):
        tags = run.data.tags
        row = table[table["split"].str.startswith(tags["split"]) & (table["source"] == f"{tags['model']} (tpe)")]
        assert abs(float(row["mean residual µm"].iloc[0]) - run.data.metrics["test/mae"]) < 1e-9
        assert abs(float(row["max residual µm"].iloc[0]) - run.data.metrics["test/max_abs_error"]) < 1e-9
    s2 = pd.read_csv(tmp_path / "reports" / sweep / "s2_mre.csv")
    assert (s2["residual variance µm²"] >= -1e-9).all() and s2["mean relative error %"].notna().all()
    logged = {a.path for a in mlflow.MlflowClient().list_artifacts(parent.info.run_id, "report")}
    assert {"report/s1_table7.md", "report/s1_table7.csv", "report/s2_mre.md", "report/s2_mre.csv"} <= logged


def _fake_sweep(models, selectors=("all",)):
    """A stand-in for MlflowClient holding one parent and a job per (model, selector): one fold each; every job
    logged the mlr and persistence baselines, equal across jobs with the same selection."""
    from types import SimpleNamespace as NS

    jobs = []
    for i, (model, selector) in enumerate((m, s) for s in selectors for m in models):
        metrics = {f"fold0/test/{m}": 1.0 + i for m in ("rmse", "mae", "mse")}
        for b, value in (("mlr", 2.0), ("persistence", 3.0)):
            metrics.update({f"fold0/baseline/{b}/test/{m}": value + selectors.index(selector)
                            for m in ("rmse", "mae", "mse")})
        tags = {"dataset": "d", "model": model, "optimizer": "tpe", "selector": selector, "protocol": "honest",
                "split": "chronological"}
        jobs.append(NS(info=NS(run_id=f"r{i}"), data=NS(tags=tags, params={"selected_sensors": selector},
                                                        metrics=metrics)))
    return NS(get_run=lambda _id: NS(info=NS(experiment_id="0")), search_runs=lambda ids, query: jobs)


def test_a_baseline_shared_by_jobs_is_one_row():
    from thermodrift.core import report

    rows = report.collect(_fake_sweep(["mlr", "mnr", "bp", "lstm"]), "parent")
    assert len(rows) == 4 + 2  # the four models, each baseline once (not once per job: 12 rows)
    for name, (_, build) in report.TABLES.items():
        table = build(rows)
        assert not table.duplicated().any(), name
    assert len(report.s2_table(rows)) == 6
    # jobs whose selections differ evaluate the baselines on other inputs: those rows stay apart
    rows = report.collect(_fake_sweep(["mlr", "bp"], selectors=("all", "correlation_top_k")), "parent")
    assert len(rows) == 4 + 2 * 2
    assert sorted(report.grid_summary(rows)["source"]) == sorted(["mlr (tpe)", "bp (tpe)", "mlr", "persistence"] * 2)
