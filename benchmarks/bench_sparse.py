"""Sparse drift benchmark: AutoML trained on a drift measured now and then against one measured every sample.

FL_THERMAL (``--data``, the workbook), target ch3, under the project's 5000 rpm split (train t < 24.13 h, test
24.13–32.13 h) and its final-block split (train t < 40.13 h, test the short runs after it). The training rows
keep ch3 only every ``--every-min`` minutes (default 30 and 120: a touch probe every half hour, every two hours;
NaN between), the temperatures and speed at full rate; the held-out rows keep every sample, so each variant is
scored on the same rows. Prints per split and spacing the held-out RMSE (µm) of ``thermodrift automl`` and its
ratio to the dense run, beside the Done-means bounds (1.3x at 30 min, 1.6x at 2 h), and MLR's held-out RMSE.

``--multirun fd:0`` (any ``generator:seed`` of ``bench_multirun.py``) checks the same on a second recording that
shares no code with the library: that benchmark's machine recorded on 6 days (one run each, logged every 60 s),
the last day held out (split ``run_holdout``), the drift thinned the same way on the other days.

The default budget is short (``--budget 24`` fits; a few minutes per split on 2 cores); ``--budget 120`` is
automl's default. Run::

    python benchmarks/bench_sparse.py [--data ../shared/data/fl_thermal/data.xlsx] [--budget FITS]
        [--every-min 30 120] [--splits fl_5000rpm fl_final]
    python benchmarks/bench_sparse.py --multirun fd:0 lumped:1     # the independent multi-day recordings
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from thermodrift.core import registry, splits
from thermodrift.core.automl import job as automl_job
from thermodrift.core.automl.search import Settings
from thermodrift.core.recording import Recording
from thermodrift.core.study import JobSpec

TARGET = "ch3(um)"
SPLITS = {"fl_5000rpm": {"train_end_h": 24.13, "test_start_h": 24.13, "test_end_h": 32.13},
          "fl_final": {"train_end_h": 40.13, "test_start_h": 40.13}}
BOUNDS = {30: 1.3, 120: 1.6}  # Done-means: sparse / dense held-out RMSE at these spacings (min)


def sparse(recording: Recording, test: np.ndarray, every_s: float, targets: list[str] = (TARGET,)) -> Recording:
    """``recording`` with ``targets`` kept only every ``every_s`` seconds outside the ``test`` rows (NaN between;
    a reading at the first row on or after each multiple of ``every_s`` from the first row)."""
    data = recording.data.copy()
    t = recording.time_s - recording.time_s[0]
    keep = np.zeros(len(t), dtype=bool)
    keep[np.unique(np.searchsorted(t, np.arange(0.0, t[-1] + 1.0, every_s)))[:-1]] = True
    keep[test] = True
    data.loc[~keep, list(targets)] = np.nan
    return Recording(data, recording.channels, recording.source, recording.notes, recording.runs().to_numpy())


def fl_spec(split: str, seed: int) -> JobSpec:
    return JobSpec(dataset="fl_thermal", model="mlr", split="time_window", split_params=SPLITS[split],
                   targets=[TARGET], seed=seed, storage=None, progress=False)


def multirun_spec(name: str, folder: Path) -> JobSpec:
    """``bench_multirun.py``'s recording ``generator:seed`` (6 days) written to ``folder``, its last day held out."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_multirun

    generator, seed = name.split(":")
    spec, _ = bench_multirun.task_spec(generator, int(seed), "last", 6, folder)
    return spec


def run(recording, spec: JobSpec, budget: int) -> dict:
    started, cpu = time.perf_counter(), time.process_time()
    result = automl_job.run(spec, Settings(budget_fits=budget), recording=recording)
    return {"rmse": result.job.summary_metrics("model")["rmse"], "mlr": result.job.summary_metrics("mlr")["rmse"],
            "wall_s": time.perf_counter() - started, "cpu_s": time.process_time() - cpu,
            "chosen": result.job.spec.model}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default="../shared/data/fl_thermal/data.xlsx", help="the FL_THERMAL workbook")
    parser.add_argument("--budget", type=int, default=24, help="automl budget (fits); 120 is its default")
    parser.add_argument("--every-min", type=float, nargs="*", default=[30.0, 120.0], help="probe spacing (min)")
    parser.add_argument("--splits", nargs="*", default=list(SPLITS), choices=list(SPLITS), help="FL_THERMAL splits")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--multirun", nargs="*", default=[], metavar="GENERATOR:SEED",
                        help="also (or with --splits and no FL split: only) bench_multirun's recordings, e.g. fd:0")
    args = parser.parse_args()
    tasks = []
    if args.splits:
        fl = registry.create("dataset", "fl_thermal", path=args.data)
        tasks += [(split, fl, fl_spec(split, args.seed), [TARGET]) for split in args.splits]
    folder = Path(tempfile.mkdtemp(prefix="bench_sparse_"))
    for name in args.multirun:
        spec = multirun_spec(name, folder)
        rec = registry.create("dataset", spec.dataset, **spec.dataset_params)
        tasks.append((name, rec, spec, rec.columns("displacement")))
    print(f"automl budget {args.budget} fits; held-out RMSE in µm, mean over the drift channels (FL_THERMAL: "
          f"{TARGET}; wall times: a loaded machine)")
    print(f"{'split':<12}{'drift every':>12}{'measured':>10}{'automl':>9}{'MLR':>8}{'ratio':>8}{'bound':>7}"
          f"{'met':>5}{'wall s':>8}  chosen")
    for split, recording, spec, targets in tasks:
        (fold,) = splits.make_split(spec.split, seed=spec.seed, **spec.split_params).folds(recording)
        dense = run(recording, spec, args.budget)
        print(f"{split:<12}{'sample':>12}{len(fold.train):>10}{dense['rmse']:>9.3f}{dense['mlr']:>8.3f}"
              f"{1.0:>8.2f}{'':>7}{'':>5}{dense['wall_s']:>8.0f}  {dense['chosen']}", flush=True)
        for minutes in args.every_min:
            rec = sparse(recording, fold.test, 60.0 * minutes, targets)
            measured = int(np.isfinite(rec.data[targets[0]].to_numpy()[fold.train]).sum())
            out = run(rec, spec, args.budget)
            ratio = out["rmse"] / dense["rmse"]
            bound = BOUNDS.get(int(minutes))
            met = "" if bound is None else ("yes" if ratio <= bound else "no")
            print(f"{split:<12}{f'{minutes:g} min':>12}{measured:>10}{out['rmse']:>9.3f}{out['mlr']:>8.3f}"
                  f"{ratio:>8.2f}{'' if bound is None else f'{bound:g}x':>7}{met:>5}{out['wall_s']:>8.0f}"
                  f"  {out['chosen']}", flush=True)


if __name__ == "__main__":
    main()
