"""Trials per second and per-trial overhead with 1, 2 and 4 worker processes on one Optuna study.

``thermodrift bench scaling [--trials 200] [--workers 1 2 4] [--postgres URL]``. The objective is trivial (a
quadratic, microseconds), so the figures are the cost of the storage and the sampler: what a worker pays per
trial besides training. Storages: a SQLite file (in a temporary folder) and, when ``--postgres`` or
``THERMODRIFT_TEST_POSTGRES`` gives a SQLAlchemy URL, PostgreSQL. Each worker is a separate process with the
storage settings ``thermodrift run`` uses (heartbeat on); the study stops at ``--trials`` finished trials across
workers. Overhead per trial = workers x wall time / trials.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import tempfile
import time
import uuid

import optuna


def _objective(trial: optuna.Trial) -> float:
    x, y = trial.suggest_float("x", -5, 5), trial.suggest_float("y", -5, 5)
    return x * x + y * y


def _worker(url: str, name: str, trials: int, seed: int, start) -> None:
    from thermodrift.core import resume
    from thermodrift.core.study import Job

    optuna.logging.set_verbosity(optuna.logging.ERROR)
    study = optuna.load_study(study_name=name, storage=Job.storage(url),
                              sampler=optuna.samplers.RandomSampler(seed=seed))
    start.wait()
    study.optimize(_objective, n_trials=trials, callbacks=[resume.StudyBudget(trials)])


def measure(url: str, workers: int, trials: int) -> tuple[float, int]:
    """Wall seconds for ``trials`` finished trials with ``workers`` processes, and the trials finished."""
    from thermodrift.core.study import Job

    name = f"scaling-{uuid.uuid4().hex[:8]}"
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    optuna.create_study(study_name=name, storage=Job.storage(url))
    ctx = mp.get_context("spawn")
    start = ctx.Event()
    procs = [ctx.Process(target=_worker, args=(url, name, trials, seed, start)) for seed in range(workers)]
    for p in procs:
        p.start()
    time.sleep(2.0)  # let every worker import and connect before the clock starts
    t0 = time.perf_counter()
    start.set()
    for p in procs:
        p.join()
    wall = time.perf_counter() - t0
    done = len(optuna.load_study(study_name=name, storage=url).get_trials(
        deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,)))
    return wall, done


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=200, help="finished trials per measurement")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--postgres", default=os.environ.get("THERMODRIFT_TEST_POSTGRES"),
                        help="SQLAlchemy URL of a PostgreSQL database (default: $THERMODRIFT_TEST_POSTGRES)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        storages = {"sqlite": f"sqlite:///{tmp}/scaling.db"}
        if args.postgres:
            storages["postgresql"] = args.postgres
        print(f"{args.trials} trials of a trivial objective; {os.cpu_count()} CPU cores")
        print(f"{'storage':12s} {'workers':>7s} {'trials':>6s} {'wall s':>7s} {'trials/s':>9s} "
              f"{'ms/trial/worker':>16s}")
        for label, url in storages.items():
            for n in args.workers:
                wall, done = measure(url, n, args.trials)
                print(f"{label:12s} {n:7d} {done:6d} {wall:7.2f} {done / wall:9.1f} {1000 * n * wall / done:16.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
