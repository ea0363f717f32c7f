"""`thermodrift run` end to end, as a user runs it: subprocesses in a scratch folder, results read from MLflow."""

import json
import os
import re
import signal
import sqlite3
import subprocess
import time
from pathlib import Path

import mlflow
import mlflow.pyfunc

from thermodrift.core.resume import KILLED_ATTR
from thermodrift.testing.data import tiny_recording


TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false"]


def runs(cwd: Path):
    mlflow.set_tracking_uri(f"sqlite:///{cwd / 'mlflow.db'}")
    return mlflow.search_runs(experiment_names=["thermodrift"], output_format="list")


def test_main_job_on_embedded_defaults(tmp_path, cli):
    """The README's main job: no arguments, the built-in dataset, SQLite for Optuna and MLflow."""
    out = cli(tmp_path, "run")
    assert out.returncode == 0, out.stderr[-2000:]
    assert (tmp_path / "mlflow.db").exists() and (tmp_path / "thermodrift.optuna.db").exists()
    (run,) = runs(tmp_path)
    m = run.data.metrics
    assert {"test/rmse", "test/mae", "test/r2", "test/max_abs_error",
            "baseline/persistence/test/rmse", "baseline/mlr/test/rmse"} <= set(m)
    assert run.data.tags["dataset"] == "demo_spindle" and m["study/n_trials"] == 20


def test_single_run_logs_held_out_metrics_and_baselines(workdir, cli):
    out = cli(workdir, "run", *TINY, "model=mlr", "n_trials=4", "seed=3")
    assert out.returncode == 0, out.stderr[-2000:]
    assert "persistence" in out.stdout and "mlr" in out.stdout
    (run,) = runs(workdir)
    m = run.data.metrics
    for name in ("rmse", "mae", "r2", "max_abs_error"):
        assert f"test/{name}" in m
        assert f"baseline/persistence/test/{name}" in m and f"baseline/mlr/test/{name}" in m
    assert 0 < m["test/rmse"] < 5 and m["test/r2"] > 0.5  # the tiny recording is nearly linear
    assert m["study/n_trials"] == 4
    tags = run.data.tags
    assert {tags[k] for k in ("dataset", "selector", "model", "optimizer", "split", "ablation")} == {
        "recording_file", "correlation_top_k", "mlr", "tpe", "condition_holdout", "none"}
    assert tags["protocol"] == "honest"
    client = mlflow.MlflowClient()
    figs = {a.path for a in client.list_artifacts(run.info.run_id, "figures")}
    assert {"figures/prediction_vs_measurement.png", "figures/residuals.png"} <= figs
    (logged,) = mlflow.search_logged_models(experiment_ids=[run.info.experiment_id], output_format="list")
    assert logged.source_run_id == run.info.run_id
    model = mlflow.pyfunc.load_model(f"models:/{logged.model_id}")
    X = tiny_recording(seed=0).data[run.data.params["selected_sensors"].split(",")]
    assert model.predict(X).shape == (len(X), 2)
    history = client.get_metric_history(run.info.run_id, "trial/value")
    assert sorted(h.step for h in history) == [0, 1, 2, 3]
    (log,) = (workdir / "outputs").glob("*/run.log")  # Hydra's job log holds the job's lines
    assert f"MLflow run {run.info.run_id} at sqlite:///mlflow.db" in log.read_text(encoding="utf-8")


def test_parallel_grid_makes_one_parent_and_tagged_children(workdir, cli):
    out = cli(workdir, "run", "-m", "hydra/launcher=joblib", "hydra.launcher.n_jobs=2",
              "model=mlr,persistence", "split=chronological,condition_holdout", *TINY, "n_trials=2")
    assert out.returncode == 0, out.stderr[-2000:]
    all_runs = runs(workdir)
    parents = [r for r in all_runs if r.data.tags.get("kind") == "sweep"]
    children = [r for r in all_runs if "mlflow.parentRunId" in r.data.tags]
    assert len(parents) == 1 and len(children) == 4
    parent = parents[0]
    assert {c.data.tags["mlflow.parentRunId"] for c in children} == {parent.info.run_id}
    assert sorted(c.data.tags["model"] for c in children) == ["mlr", "mlr", "persistence", "persistence"]
    assert parent.info.status == "FINISHED"
    artifacts = [a.path for a in mlflow.MlflowClient().list_artifacts(parent.info.run_id)]
    assert "grid.csv" in artifacts
    sweep_dirs = list((workdir / "multirun").iterdir())
    assert len(sweep_dirs) == 1 and all((sweep_dirs[0] / str(i)).is_dir() for i in range(4))
    # the terminal: one summary table of all jobs, then the parent run's id
    lines = out.stdout.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("grid: 4 jobs"))
    header = lines[head + 1].split()
    assert header[:5] == ["dataset", "selector", "model", "optimizer", "split"]
    assert {"disp_z_um", "disp_x_um", "mlr", "persistence", "wall_s"} <= set(header)
    assert sum(ln.startswith("tiny.csv") for ln in lines[head + 2:head + 6]) == 4
    assert f"parent MLflow run {parent.info.run_id}" in out.stdout
    # the parent carries the best compensation model's (by validation RMSE) metrics and params
    assert {c.data.tags["model"] for c in children if "reference" in c.data.tags} == {"persistence"}
    best = min((c for c in children if c.data.tags["model"] == "mlr"), key=lambda c: c.data.metrics["valid/best_rmse"])
    assert parent.data.tags["best_run_id"] == best.info.run_id
    assert parent.data.metrics["test/rmse"] == best.data.metrics["test/rmse"]
    assert parent.data.params["model.name"] == best.data.tags["model"]


def test_rerun_says_resumed_with_stored_counts_and_logs_the_stored_trials(workdir, cli):
    first = cli(workdir, "run", *TINY, "model=mlr", "n_trials=2")
    assert first.returncode == 0 and " resumed: " not in first.stdout, first.stderr[-2000:]
    second = cli(workdir, "run", *TINY, "model=mlr", "n_trials=2")
    assert second.returncode == 0, second.stderr[-2000:]
    (line,) = [ln for ln in second.stdout.splitlines() if " resumed: " in ln]
    assert line.startswith("study recording_file-") and line.endswith("resumed: 2 of 2 trials complete, 0 to run")
    latest = max(runs(workdir), key=lambda r: r.info.start_time)
    history = mlflow.MlflowClient().get_metric_history(latest.info.run_id, "trial/value")
    assert sorted(h.step for h in history) == [0, 1]


def test_untuned_job_output_names_targets_references_and_figures(workdir, cli):
    out = cli(workdir, "run", *TINY, "model=mlr", "n_trials=0")
    assert out.returncode == 0, out.stderr[-2000:]
    text = out.stdout
    assert "targets (µm): disp_z_um, disp_x_um" in text and "untuned (n_trials=0)" in text
    # untuned MLR on its defaults is the MLR baseline, and the output says so
    assert "note: the model's held-out predictions equal the mlr baseline's (within 0.001 µm)" in text
    assert "persistence reads the measured target of the previous sample: a reference, not a compensation model" \
        in text
    (run,) = runs(workdir)
    assert f"figures: {run.info.artifact_uri}/figures/" in text
    assert run.info.run_name.startswith("tiny.csv · mlr · ")
    assert run.data.metrics["study/n_trials"] == 0 and run.data.tags["same_as"] == "mlr"
    assert run.data.tags["optuna.storage"] == "sqlite:///thermodrift.optuna.db"
    (inp,) = run.inputs.dataset_inputs
    assert inp.dataset.name == "tiny.csv" and "tiny" in inp.dataset.source


def test_bad_input_is_one_line_and_exit_2(workdir, cli):
    wrong_group = cli(workdir, "run", *TINY, "model=no_such_model")
    assert wrong_group.returncode == 2
    assert "Traceback" not in wrong_group.stderr
    missing = cli(workdir, "run", "dataset=recording_file", "dataset.params.table=nope.csv",
                  "dataset.params.manifest=tiny.yaml")
    assert missing.returncode == 2 and "Traceback" not in missing.stderr
    lines = [ln for ln in missing.stderr.splitlines() if ln.startswith("thermodrift: error:")]
    assert len(lines) == 1 and "nope.csv" in lines[0]
    bad_target = cli(workdir, "run", *TINY, "targets=[T_ambient]")  # an input (a temperature could be a target)
    assert bad_target.returncode == 2 and "T_ambient" in bad_target.stderr and "Traceback" not in bad_target.stderr
    assert "role ambient, an input" in bad_target.stderr


def test_missing_recording_file_and_verb_errors_are_one_clean_line(workdir, cli):
    out = cli(workdir, "run", "dataset=recording_file")
    assert out.returncode == 2 and "???" not in out.stderr and "--manifest" not in out.stderr
    assert out.stderr.strip().splitlines() == [
        "thermodrift: error: dataset.params.table, dataset.params.manifest have no value: add "
        "dataset.params.table=<value> dataset.params.manifest=<value> to the command"]
    no_manifest = cli(workdir, "run", "dataset=recording_file", "dataset.params.table=tiny.csv",
                      "dataset.params.manifest=nope.yaml")
    assert no_manifest.returncode == 2 and "nope.yaml" in no_manifest.stderr
    assert "--manifest" not in no_manifest.stderr
    for verb in (["simulate", "--hours", "-1", "--out", "sim"], ["calibrate", "tiny.csv", "--manifest", "nope.yaml"]):
        out = cli(workdir, *verb)
        # a terminal shows each \r- or \n-separated piece from the line start: the error has a piece to itself
        pieces = [p.strip() for p in re.split(r"[\r\n]", out.stderr) if p.strip()]
        assert out.returncode == 2 and pieces[-1].startswith("thermodrift: error:"), (verb, out.stderr)
        assert not any("%|" in p and "error" in p for p in pieces)


def _complete_trials(db: Path) -> list[tuple[int, float]]:
    if not db.exists():
        return []
    try:
        with sqlite3.connect(db, timeout=1) as con:
            return con.execute("SELECT t.number, v.value FROM trials t JOIN trial_values v USING (trial_id) "
                               "WHERE t.state = 'COMPLETE' ORDER BY t.number").fetchall()
    except sqlite3.OperationalError:
        return []


def _budgeted_trials(db: Path) -> int:
    """Finished trials that count against the budget: complete, pruned or failed, but not failed by a kill."""
    with sqlite3.connect(db, timeout=1) as con:
        return con.execute("SELECT COUNT(*) FROM trials t WHERE t.state IN ('COMPLETE', 'PRUNED', 'FAIL') AND NOT "
                           "EXISTS (SELECT 1 FROM trial_user_attributes a WHERE a.trial_id = t.trial_id AND a.key = ?)",
                           (KILLED_ATTR,)).fetchone()[0]


def test_killed_study_resumes_and_keeps_completed_trials(workdir, cli):
    args = ["run", *TINY, "model=bp", "model.params.trainer.epochs=60", "n_trials=8", "optimizer=random"]
    proc = subprocess.Popen([*cli.exe, *args], cwd=workdir, env=cli.env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, start_new_session=True)
    db = workdir / "thermodrift.optuna.db"
    deadline = time.time() + 240
    while len(_complete_trials(db)) < 2 and time.time() < deadline and proc.poll() is None:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    before = _complete_trials(db)
    assert 2 <= len(before) < 8, f"kill came too late or too early: {len(before)} complete trials"
    out = cli(workdir, *args)
    assert out.returncode == 0, out.stderr[-2000:]
    after = _complete_trials(db)
    assert set(before) <= set(after), "completed trials were lost or changed"
    assert _budgeted_trials(db) == 8  # the budget counts finished trials (a pruned one too), not the killed one
    (run,) = [r for r in runs(workdir) if r.info.status == "FINISHED"]
    assert run.data.metrics["study/n_trials"] >= 8


def test_plugins_json_lists_components_with_origins(workdir, cli):
    out = cli(workdir, "plugins", "--json")
    assert out.returncode == 0, out.stderr
    listing = json.loads(out.stdout)["components"]
    assert len(listing["selector"]) >= 3 and len(listing["model"]) >= 2 and len(listing["optimizer"]) >= 4
    builtin = {c["name"]: c["origin"] for c in listing["optimizer"]}
    assert builtin["tpe"] == "thermodrift" and builtin["random"] == "thermodrift"


def test_every_verb_has_help(workdir, cli):
    for verb in ("plugins", "validate", "simulate", "calibrate", "bench"):
        out = cli(workdir, verb, "--help")
        assert out.returncode == 0 and "usage:" in out.stdout, (verb, out.stderr[-500:])
    out = cli(workdir, "run", "--help")
    assert out.returncode == 0 and "model" in out.stdout
