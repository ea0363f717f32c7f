"""`thermodrift report` writes S3's tables from tiny runs of the S3 presets: the Table 13/15 analogue per protocol
with DLTK's RMSE reduction, the efficiency table (Table 14), the ablation table and Table 16."""

import os
import subprocess
import sys

import mlflow
import pandas as pd
import pytest

from thermodrift.testing.data import tiny_recording

EXE = [sys.executable, "-m", "thermodrift.core.cli"]
TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false", "selector.params.n_iterations=2", "selector.params.optimizer_params={population_size: 4}"]
NETS = ["n_trials=0", "model.params.trainer.epochs=2", "model.params.trainer.t0=1"]
METRICS = ["RMSE µm", "MSE µm²", "MAE µm", "R²", "EV", "VAF %"]


def _sweep(folder, *args) -> pd.DataFrame:
    """Run one grid in ``folder`` and ``thermodrift report`` on it; the report's folder."""
    folder.mkdir()
    tiny_recording(seed=0).write(folder / "tiny.csv", folder / "tiny.yaml")
    env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true"}
    env.pop("THERMODRIFT_SWEEP_ID", None)
    out = subprocess.run([*EXE, "run", "-m", *TINY, *args], cwd=folder, capture_output=True, text=True, timeout=900,
                         env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    (sweep,) = [p.name for p in (folder / "multirun").iterdir()]
    rep = subprocess.run([*EXE, "report", sweep], cwd=folder, capture_output=True, text=True, timeout=300, env=env)
    assert rep.returncode == 0, rep.stderr[-2000:]
    return folder / "reports" / sweep


def _runs(folder):
    mlflow.set_tracking_uri(f"sqlite:///{folder / 'mlflow.db'}")
    return [r for r in mlflow.search_runs(experiment_names=["thermodrift"], output_format="list")
            if r.data.tags.get("kind") != "sweep"]


def test_the_comparison_preset_reports_table13_the_reduction_and_table14(tmp_path):
    folder = tmp_path / "cmp"
    report = _sweep(folder, "experiment=s3_rbmox_dltk", "+s3_arm=dltk,bp,lstm,tcn_lstm",
                    "split=chronological,s3_paper", *NETS)
    table = pd.read_csv(report / "s3_table13.csv")
    assert list(table.columns) == ["protocol", "split", "source", *METRICS]
    assert set(table["protocol"]) == {"honest", "paper"}
    sources = {"dltk (rbmox)", "bp (rbmox)", "lstm (rbmox)", "tcn_lstm (rbmox)", "persistence", "mlr",
               "transfer_function"}
    for _, part in table.groupby("protocol"):
        assert set(part["source"]) == sources and len(part) == len(sources)  # a baseline once per split
        assert part["RMSE µm"].is_monotonic_increasing
    assert (table["VAF %"] - 100 * table["EV"]).abs().max() < 1e-9
    for run in _runs(folder):  # every tuned row is its job's logged held-out metrics
        tags = run.data.tags
        row = table[(table["protocol"] == tags["protocol"]) & (table["source"] == f"{tags['model']} (rbmox)")]
        assert abs(row["RMSE µm"].iloc[0] - run.data.metrics["test/rmse"]) < 1e-9
        assert abs(row["VAF %"].iloc[0] - run.data.metrics["test/vaf"]) < 1e-9

    reduction = pd.read_csv(report / "s3_rmse_reduction.csv")
    for protocol, part in reduction.groupby("protocol"):
        assert list(part["against"])[:3] == ["bp (rbmox)", "lstm (rbmox)", "tcn_lstm (rbmox)"]
        assert set(part["against"]) == sources - {"dltk (rbmox)"}
        rmse = table[table["protocol"] == protocol].set_index("source")["RMSE µm"]
        for _, r in part.iterrows():
            assert r["RMSE reduction %"] == pytest.approx(100 * (1 - rmse["dltk (rbmox)"] / rmse[r["against"]]))

    cost = pd.read_csv(report / "s3_efficiency.csv")
    assert list(cost.columns) == ["protocol", "split", "source", "training s", "ms per sample (batch)",
                                  "ms per one-sample call", "parameters"]
    assert len(cost) == 8 and (cost[["training s", "ms per sample (batch)", "parameters"]] > 0).all().all()
    assert cost.groupby("protocol")["parameters"].nunique().eq(4).all()  # four different networks
    assert not (report / "s3_ablation.csv").exists() and not (report / "s3_table16.csv").exists()


def test_the_ablation_preset_reports_five_different_networks(tmp_path):
    report = _sweep(tmp_path / "abl", "experiment=s3_dltk_ablation", *NETS)
    table = pd.read_csv(report / "s3_ablation.csv")
    assert list(table["ablation"]) == ["full", "no_deform", "no_lstm", "no_transformer", "no_kan"]
    assert list(table.columns) == ["protocol", "split", "ablation", "source", *METRICS, "parameters", "training s"]
    assert table["parameters"].nunique() == 5 and table["RMSE µm"].notna().all()
    assert not (report / "s3_table13.csv").exists()  # no comparison in an ablation sweep


def test_the_selection_preset_reports_table16(tmp_path):
    report = _sweep(tmp_path / "sel", "experiment=s3_selection")
    table = pd.read_csv(report / "s3_table16.csv")
    assert list(table.columns) == ["protocol", "split", "selector", "optimizer", "best correlation",
                                   "reached at iteration", "sensors"]
    assert sorted(table["optimizer"]) == ["fa", "gwo", "pso"]
    # on 5 sensors and 8 trials a setting may leave every sensor noise: a fitness below 0 (hdbscan_pso's slope)
    assert (table["best correlation"] <= 1).all() and table["reached at iteration"].between(1, 2).all()
    assert table["best correlation"].is_monotonic_decreasing
    logged = {r.data.params["selector.params.optimizer"]: r.data.metrics["selector/best_fitness"]
              for r in _runs(tmp_path / "sel")}
    assert dict(zip(table["optimizer"], table["best correlation"])) == pytest.approx(logged)
