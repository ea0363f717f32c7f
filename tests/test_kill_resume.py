"""SIGKILL a real `thermodrift run` mid-trial, then run the same command: nothing is left RUNNING.

The resume starts straight after the kill, inside Optuna's heartbeat grace period; the killed trial's owner
(host, pid, process start time) tells that it is dead. Results are read from the SQLite files afterwards.
"""

import os
import signal
import sqlite3
import subprocess
import time
from pathlib import Path

import mlflow
import pytest

ARGS = ["run", "dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false", "model=bp", "model.params.trainer.epochs=100", "optimizer=random"]


def _states(db: Path) -> dict[str, int]:
    """Trials by state; ``IN_OBJECTIVE``: RUNNING trials whose objective has begun (their owner is recorded)."""
    try:
        with sqlite3.connect(db, timeout=1) as con:
            out = dict(con.execute("SELECT state, COUNT(*) FROM trials GROUP BY state").fetchall())
            out["IN_OBJECTIVE"] = con.execute(
                "SELECT COUNT(*) FROM trials t JOIN trial_user_attributes a USING (trial_id) "
                "WHERE t.state = 'RUNNING' AND a.key = 'worker'").fetchone()[0]
            return out
    except sqlite3.OperationalError:
        return {}


def _run_states(cwd: Path) -> list[tuple[str, dict]]:
    mlflow.set_tracking_uri(f"sqlite:///{cwd / 'mlflow.db'}")
    return [(r.info.status, r.data.tags) for r in mlflow.search_runs(experiment_names=["thermodrift"],
                                                                      output_format="list")]


def _second_trial_running(db: Path) -> bool:
    states = _states(db)
    return states.get("COMPLETE", 0) >= 1 and states.get("IN_OBJECTIVE", 0) == 1


def _kill_mid_trial(cli, cwd: Path, n_trials: int) -> None:
    """Start the job and SIGKILL its process group once a trial completed and the next one is RUNNING."""
    proc = subprocess.Popen([*cli.exe, *ARGS, f"n_trials={n_trials}"], cwd=cwd, env=cli.env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    db, deadline = cwd / "thermodrift.optuna.db", time.time() + 240
    while time.time() < deadline and proc.poll() is None:
        if _second_trial_running(db):
            os.killpg(proc.pid, signal.SIGSTOP)  # frozen: the trial cannot end between this check and the kill
            if _second_trial_running(db):
                break
            os.killpg(proc.pid, signal.SIGCONT)
        time.sleep(0.02)
    # trials of 100 epochs last long enough that the polling above sees the second one running
    assert proc.poll() is None, f"the job ended before its second trial was seen running: {_states(db)}"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    states = _states(db)
    assert states.get("RUNNING") == 1 and states.get("COMPLETE", 0) < n_trials, f"kill missed a trial: {states}"


@pytest.mark.parametrize("resume_trials", [3, 1], ids=["trials_left", "budget_already_met"])
def test_resume_after_sigkill_leaves_nothing_running(workdir, resume_trials, cli):
    _kill_mid_trial(cli, workdir, 3)
    (killed_run,) = [tags for status, tags in _run_states(workdir) if status == "RUNNING"]
    complete_before = _states(workdir / "thermodrift.optuna.db")["COMPLETE"]
    out = cli(workdir, *ARGS, f"n_trials={resume_trials}", timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    states = _states(workdir / "thermodrift.optuna.db")
    assert states.get("RUNNING", 0) == 0 and states["FAIL"] == 1
    assert states["COMPLETE"] == max(resume_trials, complete_before)  # the killed trial took no budget
    runs = _run_states(workdir)
    assert [status for status, _ in runs].count("RUNNING") == 0
    (killed,) = [tags for status, tags in runs if status == "KILLED"]
    (resumed,) = [tags for status, tags in runs if status == "FINISHED"]
    assert killed["worker"] == killed_run["worker"] and "died" in killed["error"]
    mlflow.set_tracking_uri(f"sqlite:///{workdir / 'mlflow.db'}")
    killed_id = [r.info.run_id for r in mlflow.search_runs(experiment_names=["thermodrift"], output_format="list")
                 if r.info.status == "KILLED"][0]
    assert resumed["resumes"] == killed_id


def test_two_workers_failing_the_same_dead_trial_do_not_crash():
    """Live workers each fail a dead worker's RUNNING trial; the one that reads it as RUNNING after the other has
    finished it (a stale snapshot) moves on instead of raising."""
    import socket

    import optuna

    from thermodrift.core import resume

    gone = subprocess.Popen(["true"])
    gone.wait()  # a pid with no process behind it
    study = optuna.create_study(storage=optuna.storages.RDBStorage("sqlite:///:memory:"))
    trial = study.ask()
    trial.set_user_attr(resume.OWNER_ATTR, f"{socket.gethostname()}:{gone.pid}:0")
    stale = study.get_trials(deepcopy=True)  # what the second worker read before the first acted
    assert resume.fail_dead_trials(study) == [trial.number]  # the first worker
    study.get_trials = lambda deepcopy=True, states=None: [t for t in stale if states is None or t.state in states]
    assert resume.fail_dead_trials(study) == []  # the second: already finished, nothing raised
    (t,) = optuna.Study(study.study_name, study._storage).get_trials()
    assert t.state == optuna.trial.TrialState.FAIL and t.user_attrs[resume.KILLED_ATTR] is True
