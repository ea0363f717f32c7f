"""Several `thermodrift run` workers on one study: started together on new stores, and on PostgreSQL with one
worker SIGKILLed mid-trial. Real processes; the storage is read afterwards."""

import os
import signal
import subprocess
import sys
import time
import uuid

import mlflow
import optuna
import pytest

from thermodrift.testing.data import tiny_recording

EXE = [sys.executable, "-m", "thermodrift.core.cli", "run"]
TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false"]


def _env() -> dict:
    env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true"}
    env.pop("THERMODRIFT_SWEEP_ID", None)
    return env


def _start(cwd, args):
    return subprocess.Popen([*EXE, *TINY, *args], cwd=cwd, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _logged_complete(cwd) -> set[int]:
    """Trial numbers that any worker's MLflow run logged as complete."""
    mlflow.set_tracking_uri(f"sqlite:///{cwd / 'mlflow.db'}")
    client = mlflow.MlflowClient()
    numbers = set()
    for run in mlflow.search_runs(experiment_names=["thermodrift"], output_format="list"):
        numbers |= {m.step for m in client.get_metric_history(run.info.run_id, "trial/complete")}
    return numbers


def test_four_runs_started_together_on_a_new_sqlite_study_all_succeed(tmp_path):
    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    workers = [_start(tmp_path, ["model=mlr", "n_trials=12", "optimizer=random"]) for _ in range(4)]
    errors = [w.communicate(timeout=600)[1] for w in workers]
    assert [w.returncode for w in workers] == [0] * 4, "\n".join(e[-1500:] for e in errors)
    (summary,) = optuna.get_all_study_summaries(f"sqlite:///{tmp_path / 'thermodrift.optuna.db'}")
    study = optuna.load_study(study_name=summary.study_name, storage=f"sqlite:///{tmp_path / 'thermodrift.optuna.db'}")
    numbers = [t.number for t in study.trials]
    assert len(numbers) == len(set(numbers)) and {t.state for t in study.trials} == {optuna.trial.TrialState.COMPLETE}
    assert 12 <= len(numbers) <= 12 + 3  # the budget is the study's; at most one extra trial per other worker
    assert _logged_complete(tmp_path) <= set(numbers)
    mlflow.set_tracking_uri(f"sqlite:///{tmp_path / 'mlflow.db'}")
    runs = mlflow.search_runs(experiment_names=["thermodrift"], output_format="list")
    assert sorted(r.info.status for r in runs) == ["FINISHED"] * 4



def test_four_workers_on_postgresql_lose_nothing_when_one_is_killed_mid_trial(tmp_path, postgres_url):
    storage = postgres_url
    name = f"workers-{uuid.uuid4().hex}"
    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    args = ["model=bp", "model.params.trainer.epochs=20", "n_trials=16", "optimizer=random", f"optuna.storage={storage}",
            f"optuna.study_name={name}"]
    workers = [_start(tmp_path, args) for _ in range(4)]
    victim, deadline = workers[0], time.time() + 300
    while time.time() < deadline and victim.poll() is None:
        try:
            study = optuna.load_study(study_name=name, storage=storage)
        except KeyError:
            time.sleep(0.2)
            continue
        owned = [t for t in study.get_trials(states=(optuna.trial.TrialState.RUNNING,))
                 if t.user_attrs.get("worker", "").split(":")[1:2] == [str(victim.pid)]]
        done = len(study.get_trials(states=(optuna.trial.TrialState.COMPLETE,)))
        if owned and done >= 1:
            break
        time.sleep(0.05)
    os.killpg(victim.pid, signal.SIGKILL)
    victim.wait()
    errors = [w.communicate(timeout=600)[1] for w in workers[1:]]
    assert [w.returncode for w in workers[1:]] == [0] * 3, "\n".join(e[-1500:] for e in errors)
    study = optuna.load_study(study_name=name, storage=storage)
    by_state = {}
    for t in study.trials:
        by_state.setdefault(t.state.name, []).append(t)
    numbers = [t.number for t in study.trials]
    assert len(numbers) == len(set(numbers)), "duplicate trial numbers"
    assert "RUNNING" not in by_state, "the killed worker's trial is still RUNNING"
    assert [t.user_attrs.get("killed") for t in by_state["FAIL"]] == [True], "the killed trial is not marked"
    assert 16 <= len(by_state["COMPLETE"]) <= 16 + 3
    assert _logged_complete(tmp_path) <= {t.number for t in by_state["COMPLETE"]}, "a completed trial was lost"
