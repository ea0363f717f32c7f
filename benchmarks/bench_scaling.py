"""Trials per second, per-trial overhead and duplicate parameter sets with 1, 2 and 4 workers on one Optuna study.

``thermodrift bench scaling [--trials 200] [--workers 1 2 4] [--optimizers random pso] [--postgres URL]``. The
objective is trivial (a quadratic in two parameters, one on a log scale; microseconds), so the figures are the cost
of the storage and the sampler: what a worker pays per trial besides training. Storages: a SQLite file (in a
temporary folder) and, when ``--postgres`` or ``THERMODRIFT_TEST_POSTGRES`` gives a SQLAlchemy URL, PostgreSQL.
Each worker is a separate process with the storage settings and the sampler ``thermodrift run`` uses (heartbeat on;
the registry's optimizer with the run's seed 0, as every worker of one study gets it); the study stops at
``--trials`` finished trials across workers. Columns: trials/s = finished trials / wall time; ms/trial/worker =
workers x wall time / trials; CPU ms/trial = the workers' user + system CPU time / trials (the database server's
own CPU not included); dup % = trials whose parameters equal an earlier trial's, per 100 trials.
"""

from __future__ import annotations

import argparse
import collections
import math
import multiprocessing as mp
import os
import resource
import tempfile
import time
import uuid

import optuna


def _objective(trial: optuna.Trial) -> float:
    x, y = trial.suggest_float("x", -5, 5), trial.suggest_float("y", 1e-3, 1e3, log=True)
    return (x - 1.3) ** 2 + (math.log10(y) - 0.4) ** 2


def _worker(url: str, name: str, optimizer: str, trials: int, start) -> None:
    from thermodrift.core import registry, resume
    from thermodrift.core.study import Job

    optuna.logging.set_verbosity(optuna.logging.ERROR)
    sampler = registry.create_sampler(optimizer, seed=0, n_trials=trials)
    study = optuna.load_study(study_name=name, storage=Job.storage(url), sampler=sampler)
    start.wait()
    study.optimize(_objective, n_trials=trials, callbacks=[resume.StudyBudget(trials)])


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def measure(url: str, optimizer: str, workers: int, trials: int) -> tuple[float, float, int, int]:
    """Wall seconds and the workers' CPU seconds for ``trials`` finished trials with ``workers`` processes, the
    trials finished and the duplicate parameter sets among them."""
    from thermodrift.core.study import Job

    name = f"scaling-{uuid.uuid4().hex[:8]}"
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    optuna.create_study(study_name=name, storage=Job.storage(url))
    ctx = mp.get_context("spawn")
    start = ctx.Event()
    procs = [ctx.Process(target=_worker, args=(url, name, optimizer, trials, start)) for _ in range(workers)]
    for p in procs:
        p.start()
    time.sleep(2.0)  # let every worker import and connect before the clock starts
    cpu0 = _children_cpu()  # spawn's import time is counted too: at most ~1 s per worker, the same in every row
    t0 = time.perf_counter()
    start.set()
    for p in procs:
        p.join()
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    done = optuna.load_study(study_name=name, storage=url).get_trials(
        deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    repeats = collections.Counter(tuple(sorted(t.params.items())) for t in done)
    return wall, cpu, len(done), sum(n - 1 for n in repeats.values())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=200, help="finished trials per measurement")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--optimizers", nargs="+", default=["random", "pso"],
                        help="registered optimizers, each built as `thermodrift run` builds it")
    parser.add_argument("--postgres", default=os.environ.get("THERMODRIFT_TEST_POSTGRES"),
                        help="SQLAlchemy URL of a PostgreSQL database (default: $THERMODRIFT_TEST_POSTGRES)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        storages = {"sqlite": f"sqlite:///{tmp}/scaling.db"}
        if args.postgres:
            storages["postgresql"] = args.postgres
        print(f"{args.trials} trials of a trivial objective; {os.cpu_count()} CPU cores")
        print(f"{'storage':11s} {'optimizer':10s} {'workers':>7s} {'trials':>6s} {'wall s':>7s} {'trials/s':>9s} "
              f"{'ms/trial/worker':>16s} {'CPU ms/trial':>13s} {'dup %':>6s}")
        for label, url in storages.items():
            for optimizer in args.optimizers:
                for n in args.workers:
                    wall, cpu, done, dup = measure(url, optimizer, n, args.trials)
                    print(f"{label:11s} {optimizer:10s} {n:7d} {done:6d} {wall:7.2f} {done / wall:9.1f} "
                          f"{1000 * n * wall / done:16.1f} {1000 * cpu / done:13.1f} {100 * dup / done:6.1f}",
                          flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
