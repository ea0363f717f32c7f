"""Clean-up after a killed job: its RUNNING Optuna trials become FAIL and its RUNNING MLflow runs KILLED.

Every trial and MLflow run records its owner: host, process id and the process's start time (the start time
tells a live process from a later one that reused the pid). An owner on this host is dead when no process
with that pid and start time exists, which is known at once, even inside Optuna's heartbeat grace period. An
owner on another host is judged by Optuna's heartbeat alone (``fail_stale_trials`` after the grace period),
since its processes cannot be seen from here.
"""

from __future__ import annotations

import os
import socket

import optuna

OWNER_ATTR = "worker"  # trial user attr and MLflow tag: "host:pid:start"
KILLED_ATTR = "killed"  # trial user attr: True when the trial's process died under it
RESUMES_TAG = "resumes"  # MLflow tag of a job run: comma-separated ids of the killed runs of the same study
STUDY_TAG = "study"  # MLflow tag of a job run: its Optuna study name


def _start_time(pid: int) -> str | None:
    """The process's start time in clock ticks since boot (Linux /proc), '' where /proc is absent, None if gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            return fh.read().rsplit(b")", 1)[1].split()[19].decode()
    except FileNotFoundError:
        return None if os.path.isdir("/proc") else ""
    except (OSError, IndexError):
        return ""


def owner() -> str:
    """This process as an owner string ``host:pid:start``."""
    pid = os.getpid()
    return f"{socket.gethostname()}:{pid}:{_start_time(pid) or ''}"


def is_dead(owner_text: str | None) -> bool:
    """Whether the owner is known to be gone: on this host, with no process of that pid and start time."""
    if not owner_text:
        return False
    parts = owner_text.rsplit(":", 2)
    if len(parts) != 3 or parts[0] != socket.gethostname() or not parts[1].isdigit():
        return False
    pid, started = int(parts[1]), parts[2]
    if pid == os.getpid():
        return False
    now = _start_time(pid)
    if now is None:
        return True
    if os.path.isdir("/proc"):
        return bool(started) and now != started
    try:  # no /proc: signal 0 tells whether the pid exists
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        return False
    return False


def claim(trial: optuna.Trial) -> None:
    """Record this process as the trial's owner (call first thing in the objective)."""
    trial.set_user_attr(OWNER_ATTR, owner())


def was_killed(trial: optuna.trial.FrozenTrial) -> bool:
    return bool(trial.user_attrs.get(KILLED_ATTR))


def fail_dead_trials(study: optuna.Study) -> list[int]:
    """Mark FAIL every RUNNING trial of ``study`` whose owner process is dead; return their numbers."""
    storage = study._storage  # Optuna offers no public way to finish another process's trial
    failed = []
    for trial in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        who = trial.user_attrs.get(OWNER_ATTR)
        if not is_dead(who):
            continue
        try:  # several live workers may find the same dead trial: whichever writes first finishes it
            storage.set_trial_user_attr(trial._trial_id, KILLED_ATTR, True)
            storage.set_trial_user_attr(trial._trial_id, "fail_reason", f"its process {who} died (killed)")
            if storage.set_trial_state_values(trial._trial_id, optuna.trial.TrialState.FAIL):
                failed.append(trial.number)
        except optuna.exceptions.UpdateFinishedTrialError:  # another worker failed it first
            pass
    return failed


def close_dead_runs(client, experiment_id: str, study_name: str | None = None) -> list[str]:
    """End as KILLED every RUNNING MLflow run of the experiment whose owner process is dead; return the ids of
    those that belonged to ``study_name`` (the runs a new job of that study resumes)."""
    resumed = []
    for run in client.search_runs([experiment_id], "attributes.status = 'RUNNING'", max_results=1000):
        tags = run.data.tags
        if not is_dead(tags.get(OWNER_ATTR)):
            continue
        client.set_tag(run.info.run_id, "error", f"its process {tags.get(OWNER_ATTR)} died (killed)")
        client.set_terminated(run.info.run_id, status="KILLED")
        if study_name is not None and tags.get(STUDY_TAG) == study_name:
            resumed.append(run.info.run_id)
    return resumed


class StudyBudget:
    """Optuna callback: stop this worker once the study holds ``budget`` finished trials (killed ones aside),
    whichever workers ran them."""

    def __init__(self, budget: int):
        self.budget = budget

    def __call__(self, study: optuna.Study, trial: optuna.trial.FrozenTrial) -> None:
        finished = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,
                                                            optuna.trial.TrialState.PRUNED,
                                                            optuna.trial.TrialState.FAIL))
        if sum(not was_killed(t) for t in finished) >= self.budget:
            study.stop()
