"""`thermodrift report`: the studies' tables from a sweep in MLflow. S1/S2's tables from a small real sweep; S3's
from tiny runs of the S3 presets: the Table 13/15 analogue per protocol with DLTK's RMSE reduction, the efficiency
table (Table 14), the ablation table and Table 16."""

import re
import shutil
from pathlib import Path

import mlflow
import pandas as pd
import pytest

from thermodrift.testing.data import tiny_recording

TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false"]


@pytest.fixture(scope="module")
def grid(tmp_path_factory, cli, empty_mlflow_db):
    """One small grid, run as a user runs it with its output going to a file (a pipe), shared by the tests below:
    two models by the two paper splits, 2 trials each; (folder, sweep id, the completed process)."""
    folder = tmp_path_factory.mktemp("grid")
    tiny_recording(seed=0).write(folder / "tiny.csv", folder / "tiny.yaml")
    shutil.copy(empty_mlflow_db, folder / "mlflow.db")
    # an empty matplotlib cache: its font scan logs INFO lines, which must not reach the output
    out = cli(folder, "run", "-m", *TINY, "model=mlr,mnr", "split=chronological,shuffled", "n_trials=2",
              "selector=all", "progress=true", env={"MPLCONFIGDIR": str(folder / "mpl")})
    assert out.returncode == 0, out.stderr[-2000:]
    (sweep,) = [p.name for p in (folder / "multirun").iterdir()]
    return folder, sweep, out


def test_grid_output_in_a_file_is_clean_and_names_its_sweep_and_report(grid):
    folder, sweep, out = grid
    text = out.stdout + out.stderr
    assert "\r" not in text and "fontManager" not in text and "matplotlib" not in text
    progress = [ln for ln in out.stderr.splitlines() if " trials finished" in ln]
    assert progress and all(re.fullmatch(r"\S+: \d+ of 2 trials finished, best inner validation RMSE [\d.]+ µm", ln)
                            for ln in progress)
    lines = out.stderr.splitlines()  # Hydra's, progress, and one line per warning (the paper protocol's)
    assert all(ln.startswith(("[", "recording_file-", "thermodrift: warning: ")) for ln in lines), out.stderr
    assert sum("split=shuffled is a paper protocol" in ln for ln in lines) == 1
    assert f"sweep {sweep}: job folders in multirun/{sweep}" in out.stdout
    (where,) = re.findall(r"logged on the parent run: file://(\S+)", out.stdout)
    assert (Path(where) / "report.md").is_file() and f"thermodrift report {sweep}" in out.stdout
    mlflow.set_tracking_uri(f"sqlite:///{folder / 'mlflow.db'}")
    children = [r for r in mlflow.search_runs(experiment_names=["thermodrift"], output_format="list")
                if "mlflow.parentRunId" in r.data.tags]
    logs = [p.read_text(encoding="utf-8") for p in sorted((folder / "multirun" / sweep).glob("*/run.log"))]
    assert len(logs) == len(children) == 4
    assert sorted(c.info.run_id for c in children) == sorted(re.search(r"MLflow run (\w+) at", t)[1] for t in logs)


def test_report_regenerates_tables_from_a_sweep(grid, cli):
    folder, sweep, _ = grid
    rep = cli(folder, "report", sweep)
    assert rep.returncode == 0, rep.stderr[-2000:]
    assert "S1 Table 7 analogue" in rep.stdout and "S2 analogue" in rep.stdout
    table = pd.read_csv(folder / "reports" / sweep / "s1_table7.csv")
    assert set(table["protocol"]) == {"paper", "honest"}
    assert {"mlr (tpe)", "mnr (tpe)", "persistence", "mlr"} <= set(table["source"])
    assert len(table) == 2 * 4  # per split: the two tuned models and the two baselines (same in both jobs)
    mlflow.set_tracking_uri(f"sqlite:///{folder / 'mlflow.db'}")
    runs = mlflow.search_runs(experiment_names=["thermodrift"], output_format="list")
    parent = next(r for r in runs if r.data.tags.get("kind") == "sweep")
    for run in (r for r in runs if r.data.tags.get("mlflow.parentRunId") == parent.info.run_id):
        tags = run.data.tags
        row = table[table["split"].str.startswith(tags["split"]) & (table["source"] == f"{tags['model']} (tpe)")]
        assert abs(float(row["mean residual µm"].iloc[0]) - run.data.metrics["test/mae"]) < 1e-9
        assert abs(float(row["max residual µm"].iloc[0]) - run.data.metrics["test/max_abs_error"]) < 1e-9
    s2 = pd.read_csv(folder / "reports" / sweep / "s2_mre.csv")
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


S3_TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
           "progress=false", "selector.params.n_iterations=2",
           "selector.params.optimizer_params={population_size: 4}"]
NETS = ["n_trials=0", "model.params.trainer.epochs=2", "model.params.trainer.t0=1"]
METRICS = ["RMSE µm", "MSE µm²", "MAE µm", "R²", "EV", "VAF %"]


def _sweep(cli, folder, *args) -> pd.DataFrame:
    """Run one grid in ``folder`` (a ``workdir``) and ``thermodrift report`` on it; the report's folder."""
    out = cli(folder, "run", "-m", *S3_TINY, *args, timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    (sweep,) = [p.name for p in (folder / "multirun").iterdir()]
    rep = cli(folder, "report", sweep, timeout=300)
    assert rep.returncode == 0, rep.stderr[-2000:]
    return folder / "reports" / sweep


def _runs(folder):
    mlflow.set_tracking_uri(f"sqlite:///{folder / 'mlflow.db'}")
    return [r for r in mlflow.search_runs(experiment_names=["thermodrift"], output_format="list")
            if r.data.tags.get("kind") != "sweep"]


def test_the_comparison_preset_reports_table13_the_reduction_and_table14(workdir, cli):
    folder = workdir
    report = _sweep(cli, folder, "experiment=s3_rbmox_dltk", "+s3_arm=dltk,bp,lstm,tcn_lstm",
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


def test_the_ablation_preset_reports_five_different_networks(workdir, cli):
    report = _sweep(cli, workdir, "experiment=s3_dltk_ablation", *NETS)
    table = pd.read_csv(report / "s3_ablation.csv")
    assert list(table["ablation"]) == ["full", "no_deform", "no_lstm", "no_transformer", "no_kan"]
    assert list(table.columns) == ["protocol", "split", "ablation", "source", *METRICS, "parameters", "training s"]
    assert table["parameters"].nunique() == 5 and table["RMSE µm"].notna().all()
    assert not (report / "s3_table13.csv").exists()  # no comparison in an ablation sweep


def test_the_selection_preset_reports_table16(workdir, cli):
    report = _sweep(cli, workdir, "experiment=s3_selection")
    table = pd.read_csv(report / "s3_table16.csv")
    assert list(table.columns) == ["protocol", "split", "selector", "optimizer", "best correlation",
                                   "reached at iteration", "sensors"]
    assert sorted(table["optimizer"]) == ["fa", "gwo", "pso"]
    # on 5 sensors and 8 trials a setting may leave every sensor noise: a fitness below 0 (hdbscan_pso's slope)
    assert (table["best correlation"] <= 1).all() and table["reached at iteration"].between(1, 2).all()
    assert table["best correlation"].is_monotonic_decreasing
    logged = {r.data.params["selector.params.optimizer"]: r.data.metrics["selector/best_fitness"]
              for r in _runs(workdir)}
    assert dict(zip(table["optimizer"], table["best correlation"])) == pytest.approx(logged)
