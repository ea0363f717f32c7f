"""The MLflow tracking server down at the start, or killed mid-grid: one line, exit 2, no completed trial lost.

A real ``mlflow server`` runs on loopback and is killed by its process group id; the Optuna storage and the
per-job ``job.json`` files are read afterwards.
"""

import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time
import urllib.request

import pytest

from thermodrift.testing.data import tiny_recording

EXE = [sys.executable, "-m", "thermodrift.core.cli", "run"]
TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false", "model=mlr", "n_trials=2"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env() -> dict:
    env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true"}
    env.pop("THERMODRIFT_SWEEP_ID", None)
    return env


@pytest.fixture()
def workdir(tmp_path):
    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    return tmp_path


def test_a_server_that_is_down_at_the_start_is_one_line_and_exit_2(workdir):
    uri = f"http://127.0.0.1:{_free_port()}"
    out = subprocess.run([*EXE, *TINY, f"tracking.uri={uri}"], cwd=workdir, env=_env(), capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    (line,) = out.stderr.strip().splitlines()
    assert uri in line and "does not answer" in line
    grid = subprocess.run([*EXE, "-m", "seed=0,1", *TINY, f"tracking.uri={uri}"], cwd=workdir, env=_env(),
                          capture_output=True, text=True, timeout=120)
    assert grid.returncode == 2 and "Traceback" not in grid.stderr and "does not answer" in grid.stderr


@pytest.fixture()
def server(tmp_path):
    """A real MLflow tracking server on loopback: (uri, process)."""
    port = _free_port()
    folder = tmp_path / "server"
    folder.mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "mlflow", "server", "--backend-store-uri",
                             f"sqlite:///{folder / 'x.db'}", "--host", "127.0.0.1", "--port", str(port),
                             "--workers", "1"], cwd=folder, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    uri = f"http://127.0.0.1:{port}"
    for _ in range(600):
        try:
            with urllib.request.urlopen(uri + "/health", timeout=1):
                break
        except OSError:
            assert proc.poll() is None, "mlflow server exited"
            time.sleep(0.2)
    yield uri, proc
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def test_a_server_killed_mid_grid_loses_no_trial_and_the_grid_ends_cleanly(workdir, server):
    uri, proc = server
    grid = subprocess.Popen([*EXE, "-m", "seed=0,1,2,3", *TINY, f"tracking.uri={uri}"], cwd=workdir, env=_env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 240
    while not list(workdir.glob("multirun/*/0/job.json")) and time.time() < deadline and grid.poll() is None:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # the server dies after the first job, while the grid goes on
    proc.wait()
    _, err = grid.communicate(timeout=300)
    assert grid.returncode == 2 and "Traceback" not in err, err[-3000:]
    summary = [ln for ln in err.splitlines() if "the grid ended" in ln]
    assert len(summary) == 1 and "jobs completed and logged: 0" in summary[0] and "of 4" in summary[0]
    jobs = {p.parent.name: json.loads(p.read_text()) for p in workdir.glob("multirun/*/*/job.json")}
    assert set(jobs) == {"0", "1", "2", "3"} and jobs["0"]["completed"]
    with sqlite3.connect(workdir / "thermodrift.optuna.db") as con:
        trials = con.execute("SELECT s.study_name, t.state FROM trials t JOIN studies s USING (study_id)").fetchall()
    assert all(state == "COMPLETE" for _, state in trials), trials
    per_study = {}
    for name, _ in trials:
        per_study[name] = per_study.get(name, 0) + 1
    assert per_study[jobs["0"]["study"]] == 2
