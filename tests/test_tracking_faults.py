"""The MLflow tracking server down at the start, killed mid-study or mid-grid: one line, exit 2, no completed
trial lost.

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

TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false", "model=mlr", "n_trials=2"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_server_that_is_down_at_the_start_is_one_line_and_exit_2(workdir, cli):
    uri = f"http://127.0.0.1:{_free_port()}"
    out = cli(workdir, "run", *TINY, f"tracking.uri={uri}", timeout=120)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    (line,) = out.stderr.strip().splitlines()
    assert uri in line and "does not answer" in line
    grid = cli(workdir, "run", "-m", "seed=0,1", *TINY, f"tracking.uri={uri}", timeout=120)
    assert grid.returncode == 2 and "Traceback" not in grid.stderr and "does not answer" in grid.stderr


def _start_server(cli, folder, port: int) -> subprocess.Popen:
    """A real MLflow tracking server on loopback, its store in ``folder``, answering /health."""
    proc = subprocess.Popen([sys.executable, "-m", "mlflow", "server", "--backend-store-uri",
                             f"sqlite:///{folder / 'x.db'}", "--host", "127.0.0.1", "--port", str(port),
                             "--workers", "1"], cwd=folder, env=cli.env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    for _ in range(600):
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=1):
                break
        except OSError:
            assert proc.poll() is None, "mlflow server exited"
            time.sleep(0.2)
    return proc


@pytest.fixture()
def server(tmp_path, cli):
    """A real MLflow tracking server on loopback: (uri, process)."""
    port = _free_port()
    folder = tmp_path / "server"
    folder.mkdir()
    proc = _start_server(cli, folder, port)
    yield f"http://127.0.0.1:{port}", proc
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def _trial_states(db) -> list[tuple[str, str]]:
    """(study name, state) of every trial in the Optuna SQLite file ``db``; [] before the schema exists."""
    try:
        with sqlite3.connect(db) as con:
            return con.execute("SELECT s.study_name, t.state FROM trials t JOIN studies s USING (study_id)").fetchall()
    except sqlite3.OperationalError:
        return []


def test_a_server_killed_mid_study_loses_no_trial_and_the_same_command_logs_the_study(workdir, server, cli):
    uri, proc = server
    job = ["run", *TINY[:4], "model=bp", "model.params.trainer.epochs=20", "n_trials=6", f"tracking.uri={uri}"]
    run = subprocess.Popen([*cli.exe, *job], cwd=workdir, env=cli.env(), stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 240
    while time.time() < deadline and run.poll() is None and \
            not any(state == "COMPLETE" for _, state in _trial_states(workdir / "thermodrift.optuna.db")):
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # the server dies while the study runs
    proc.wait()
    _, err = run.communicate(timeout=300)
    states = _trial_states(workdir / "thermodrift.optuna.db")
    assert 1 <= len(states) < 6 + 1 and run.returncode == 2 and "Traceback" not in err, err[-3000:]
    (line,) = err.strip().splitlines()
    assert "stopped answering" in line and "every completed trial is kept in study" in line
    # The study went on without the server: the whole budget completed, nothing left RUNNING.
    assert [state for _, state in states] == ["COMPLETE"] * 6
    # The same command once the server is back: the study resumes complete and its result is logged.
    proc = _start_server(cli, workdir / "server", int(uri.rsplit(":", 1)[1]))
    try:
        again = cli(workdir, *job, timeout=300)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert again.returncode == 0, again.stderr[-3000:]
    assert [state for _, state in _trial_states(workdir / "thermodrift.optuna.db")] == ["COMPLETE"] * 6


def test_a_server_killed_mid_grid_loses_no_trial_and_the_grid_ends_cleanly(workdir, server, cli):
    uri, proc = server
    grid = subprocess.Popen([*cli.exe, "run", "-m", "seed=0,1,2,3", *TINY, f"tracking.uri={uri}"], cwd=workdir,
                            env=cli.env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
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
