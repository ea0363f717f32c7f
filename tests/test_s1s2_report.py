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
        row = table[(table["split"] == tags["split"]) & (table["source"] == f"{tags['model']} (tpe)")]
        assert abs(float(row["mean residual µm"].iloc[0]) - run.data.metrics["test/mae"]) < 1e-9
        assert abs(float(row["max residual µm"].iloc[0]) - run.data.metrics["test/max_abs_error"]) < 1e-9
    s2 = pd.read_csv(tmp_path / "reports" / sweep / "s2_mre.csv")
    assert (s2["residual variance µm²"] >= -1e-9).all() and s2["mean relative error %"].notna().all()
    logged = {a.path for a in mlflow.MlflowClient().list_artifacts(parent.info.run_id, "report")}
    assert {"report/s1_table7.md", "report/s1_table7.csv", "report/s2_mre.md", "report/s2_mre.csv"} <= logged
