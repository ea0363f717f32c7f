"""Sparse drift benchmark: AutoML trained on a drift measured now and then against one measured every sample.

FL_THERMAL (``--data``, the workbook), target ch3, under the project's 5000 rpm split (train t < 24.13 h, test
24.13–32.13 h) and its final-block split (train t < 40.13 h, test the short runs after it). The training rows
keep ch3 only every ``--every-min`` minutes (default 30 and 120: a touch probe every half hour, every two hours;
NaN between), the temperatures and speed at full rate; the held-out rows keep every sample, so each variant is
scored on the same rows. Prints per split and spacing the held-out RMSE (µm) of ``thermodrift automl`` and its
ratio to the dense run, beside the Done-means bounds (1.3x at 30 min, 1.6x at 2 h), and MLR's held-out RMSE.

The default budget is short (``--budget 24`` fits; a few minutes per split on 2 cores); ``--budget 120`` is
automl's default. Run::

    python benchmarks/bench_sparse.py [--data ../shared/data/fl_thermal/data.xlsx] [--budget FITS]
        [--every-min 30 120] [--splits fl_5000rpm fl_final]
"""

from __future__ import annotations

import argparse
import time

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


def sparse(recording: Recording, test: np.ndarray, every_s: float) -> Recording:
    """``recording`` with ch3 kept only every ``every_s`` seconds outside the ``test`` rows (NaN between)."""
    data = recording.data.copy()
    t = recording.time_s - recording.time_s[0]
    keep = np.zeros(len(t), dtype=bool)
    keep[np.unique(np.searchsorted(t, np.arange(0.0, t[-1] + 1.0, every_s)))[:-1]] = True
    keep[test] = True
    data.loc[~keep, TARGET] = np.nan
    return Recording(data, recording.channels, recording.source, recording.notes)


def run(recording, split: str, budget: int, seed: int) -> dict:
    spec = JobSpec(dataset="fl_thermal", model="mlr", split="time_window", split_params=SPLITS[split],
                   targets=[TARGET], seed=seed, storage=None, progress=False)
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
    parser.add_argument("--splits", nargs="*", default=list(SPLITS), choices=list(SPLITS))
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    recording = registry.create("dataset", "fl_thermal", path=args.data)
    print(f"automl budget {args.budget} fits, target {TARGET}; held-out RMSE in µm (wall times: a loaded machine)")
    print(f"{'split':<12}{'ch3 every':>10}{'measured':>10}{'automl':>9}{'MLR':>8}{'ratio':>8}{'bound':>7}"
          f"{'met':>5}{'wall s':>8}  chosen")
    for split in args.splits:
        (fold,) = splits.make_split("time_window", **SPLITS[split]).folds(recording)
        dense = run(recording, split, args.budget, args.seed)
        print(f"{split:<12}{'sample':>10}{len(fold.train):>10}{dense['rmse']:>9.3f}{dense['mlr']:>8.3f}"
              f"{1.0:>8.2f}{'':>7}{'':>5}{dense['wall_s']:>8.0f}  {dense['chosen']}", flush=True)
        for minutes in args.every_min:
            rec = sparse(recording, fold.test, 60.0 * minutes)
            measured = int(np.isfinite(rec.data[TARGET].to_numpy()[fold.train]).sum())
            out = run(rec, split, args.budget, args.seed)
            ratio = out["rmse"] / dense["rmse"]
            bound = BOUNDS.get(int(minutes))
            met = "" if bound is None else ("yes" if ratio <= bound else "no")
            print(f"{split:<12}{f'{minutes:g} min':>10}{measured:>10}{out['rmse']:>9.3f}{out['mlr']:>8.3f}"
                  f"{ratio:>8.2f}{'' if bound is None else f'{bound:g}x':>7}{met:>5}{out['wall_s']:>8.0f}"
                  f"  {out['chosen']}", flush=True)


if __name__ == "__main__":
    main()
