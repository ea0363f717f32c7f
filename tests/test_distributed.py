"""Several `thermodrift run` workers on one study: started together on new stores, on PostgreSQL with one
worker SIGKILLed mid-trial, as jobs of Hydra's submitit launcher, and population samplers in four processes
(no cell handed out twice, duplicate parameter sets). Real processes; the storage is read afterwards."""

import collections
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import uuid

import mlflow
import optuna
import pytest

from thermodrift.testing.data import tiny_recording

TINY = ["dataset=recording_file", "dataset.params.table=tiny.csv", "dataset.params.manifest=tiny.yaml",
        "progress=false"]


def _start(cli, cwd, args):
    return subprocess.Popen([*cli.exe, "run", *TINY, *args], cwd=cwd, env=cli.env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _logged_complete(cwd) -> set[int]:
    """Trial numbers that any worker's MLflow run logged as complete."""
    mlflow.set_tracking_uri(f"sqlite:///{cwd / 'mlflow.db'}")
    client = mlflow.MlflowClient()
    numbers = set()
    for run in mlflow.search_runs(experiment_names=["thermodrift"], output_format="list"):
        numbers |= {m.step for m in client.get_metric_history(run.info.run_id, "trial/complete")}
    return numbers


def test_four_runs_started_together_on_a_new_sqlite_study_all_succeed(tmp_path, cli):
    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    workers = [_start(cli, tmp_path, ["model=mlr", "n_trials=12", "optimizer=random"]) for _ in range(4)]
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


def _frozen_inside(proc, name: str, storage: str, number: int) -> bool:
    """Stop ``proc`` (SIGSTOP) and tell whether its trial ``number`` is still RUNNING, read afresh from the storage:
    then the kill that follows lands inside that trial. Otherwise the trial ended between the poll and the stop,
    and the process goes on."""
    os.killpg(proc.pid, signal.SIGSTOP)
    running = optuna.load_study(study_name=name, storage=storage).get_trials(
        deepcopy=False, states=(optuna.trial.TrialState.RUNNING,))
    if number in {t.number for t in running}:
        return True
    os.killpg(proc.pid, signal.SIGCONT)
    return False


def test_four_workers_on_postgresql_lose_nothing_when_one_is_killed_mid_trial(tmp_path, postgres_url, cli):
    storage = postgres_url
    name = f"workers-{uuid.uuid4().hex}"
    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    # trials long enough (bp, 200 epochs) that the victim spends most of its time inside one, where it is killed
    args = ["model=bp", "model.params.trainer.epochs=200", "n_trials=16", "optimizer=random", "optuna.pruner=none",
            f"optuna.storage={storage}", f"optuna.study_name={name}"]
    workers = [_start(cli, tmp_path, args) for _ in range(4)]
    victim, deadline = workers[0], time.time() + 300
    while time.time() < deadline and victim.poll() is None:
        try:
            study = optuna.load_study(study_name=name, storage=storage)
        except KeyError:
            time.sleep(0.2)
            continue
        owned = [t.number for t in study.get_trials(states=(optuna.trial.TrialState.RUNNING,))
                 if t.user_attrs.get("worker", "").split(":")[1:2] == [str(victim.pid)]]
        done = len(study.get_trials(states=(optuna.trial.TrialState.COMPLETE,)))
        if owned and done >= 1 and _frozen_inside(victim, name, storage, owned[0]):
            break
        time.sleep(0.05)
    assert victim.poll() is None, "the worker to kill ended first:\n" + victim.communicate()[1][-1500:]
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


def _storage_url(kind, tmp_path, request) -> str:
    return f"sqlite:///{tmp_path / 'study.db'}" if kind == "sqlite" else request.getfixturevalue("postgres_url")


@pytest.mark.parametrize("kind", ["postgresql"])  # the cluster's storage; SQLite is the same code path in Optuna
def test_a_submitit_grid_of_two_jobs_shares_one_study_and_loses_nothing(tmp_path, kind, request, cli):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher", reason="pip install 'thermodrift[cluster]'")
    storage, name = _storage_url(kind, tmp_path, request), f"cluster-{uuid.uuid4().hex}"
    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    # +copy=1,2 only makes two copies of one job; submitit_local runs each in its own process.
    out = cli(tmp_path, "run", "-m", "hydra/launcher=submitit_local", "+copy=1,2", *TINY, "model=mlr", "n_trials=10",
              "optimizer=pso", f"optuna.storage={storage}", f"optuna.study_name={name}")
    assert out.returncode == 0, out.stderr[-2000:]
    (sweep,) = (tmp_path / "multirun").iterdir()
    assert len(list((sweep / ".submitit").glob("*/*_result.pkl"))) == 2  # two submitit jobs, each its own process
    jobs = [json.loads((sweep / str(i) / "job.json").read_text()) for i in range(2)]
    assert [(j["study"], j["completed"]) for j in jobs] == [(name, True)] * 2
    study = optuna.load_study(study_name=name, storage=storage)
    numbers = [t.number for t in study.trials]
    assert len(numbers) == len(set(numbers)) and {t.state for t in study.trials} == {optuna.trial.TrialState.COMPLETE}
    assert 10 <= len(numbers) <= 11  # the study's budget; the other job may finish the one trial it runs
    assert _logged_complete(tmp_path) <= set(numbers), "a trial that a job logged as complete is not in the study"
    cells = [(t.system_attrs["pso:gen"], t.system_attrs["pso:slot"]) for t in study.trials if "pso:slot" in t.system_attrs]
    assert len(cells) == len(set(cells)), "a PSO particle move was handed to both jobs"


WORKER = textwrap.dedent("""
    import math, sys, optuna
    from thermodrift.core import registry, resume
    from thermodrift.core.study import Job
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    storage, name, optimizer, budget = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    def objective(trial):  # cheap, so the four workers ask at nearly the same instants
        x, y = trial.suggest_float("x", -5, 5), trial.suggest_float("y", 1e-3, 1e3, log=True)
        return (x - 1.3) ** 2 + (math.log10(y) - 0.4) ** 2
    sampler = registry.create_sampler(optimizer, seed=0, n_trials=budget)  # as every `thermodrift run` worker
    study = optuna.load_study(study_name=name, storage=Job.storage(storage), sampler=sampler)
    study.optimize(objective, n_trials=budget, callbacks=[resume.StudyBudget(budget)])
""")


@pytest.mark.parametrize("kind, optimizer", [("sqlite", "pso"), ("postgresql", "pso"), ("sqlite", "fa")])
def test_four_processes_of_a_population_sampler_share_no_cell_and_repeat_no_parameters(tmp_path, kind, optimizer,
                                                                                       request, cli):
    """PSO moves particles asynchronously, FA a generation at a time; both claim every (generation, slot)."""
    storage, name, budget = _storage_url(kind, tmp_path, request), f"cells-{uuid.uuid4().hex}", 100
    optuna.create_study(study_name=name, storage=storage)
    workers = [subprocess.Popen([sys.executable, "-c", WORKER, storage, name, optimizer, str(budget)],
                                env=cli.env(), stderr=subprocess.PIPE, text=True) for _ in range(4)]
    errors = [w.communicate(timeout=600)[1] for w in workers]
    assert [w.returncode for w in workers] == [0] * 4, "\n".join(e[-1500:] for e in errors)
    study = optuna.load_study(study_name=name, storage=storage)
    trials = study.get_trials(states=(optuna.trial.TrialState.COMPLETE,))
    assert budget <= len(trials) == len(study.trials) <= budget + 3
    params = collections.Counter(tuple(sorted(t.params.items())) for t in trials)
    duplicates = sum(n - 1 for n in params.values())
    assert duplicates <= 0.01 * len(trials), f"{duplicates} duplicate parameter sets in {len(trials)} trials"
    # Every member trial holds exactly one claim, and each claim names one trial.
    prefix = f"{optimizer}:claim:"
    claims = {k: v for k, v in study._storage.get_study_system_attrs(study._study_id).items() if k.startswith(prefix)}
    members = [t for t in trials if f"{optimizer}:slot" in t.system_attrs]
    assert len(members) >= len(trials) - 4  # all but the first trials, drawn before any result existed
    assert sorted(claims.values()) == sorted(t._trial_id for t in members)
    for t in members:
        (key,) = [k for k, v in claims.items() if v == t._trial_id]
        gen, slot = (int(v) for v in key.split(":")[-3:-1])
        assert (t.system_attrs[f"{optimizer}:gen"], t.system_attrs[f"{optimizer}:slot"]) == (gen, slot)
    if optimizer == "pso":  # asynchronous: a (move, particle) cell is never handed out twice
        cells = [(t.system_attrs["pso:gen"], t.system_attrs["pso:slot"]) for t in members]
        assert len(cells) == len(set(cells))
