"""The buildings part of ``bench_automl.py --buildings``: ``thermodrift automl`` against FLAML and the stochastic
grey-box on the three real houses (dataset ``buildings``, target ``yTi``), the last two weeks held out
(split ``chronological``, ``test_last_h=336``), held-out RMSE in K one step (15 min) and 24 h ahead.

* automl: ``job.run`` at ``--building-budget`` fits over ``--building-families`` (default mlr, transfer_function
  and greybox: the search as a user runs it on a house, without the neural families that would not finish on a
  shared two-core machine); per horizon the scores of :func:`thermodrift.core.horizons.scores` (a model that reads
  only inputs predicts the same at both; persistence reads the target as old as the horizon);
* FLAML (the ``compare`` extra), given automl's wall time, one core, time-ordered 25 % validation: on the raw
  inputs (Ta, Ps, Thm; the same at both horizons), and on the inputs plus the indoor temperature as old as the
  horizon (``+lag``);
* the grey-box's forward selection and the one-state model, as ``bench_greybox.py --houses`` measures them (the
  Kalman one-step prediction and the 24 h-ahead prediction from the filtered state a day before), read from
  ``--greybox-json`` when given (it takes minutes per house), else left out.

Nothing here is tuned to these houses.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from thermodrift.core import horizons, registry, splits
from thermodrift.core.automl import job as automl_job
from thermodrift.core.automl.search import Settings
from thermodrift.core.metrics import rmse
from thermodrift.core.study import JobSpec

import flaml_baseline  # the comparison, beside this script (bench_automl.py puts the folder on the path)

HOUSES = (1, 2, 3)
HOLDOUT_H = 336
HORIZONS_H = (0, 24)
FAMILIES = ["mlr", "transfer_function", "greybox"]
INPUTS = ["Ta", "Ps", "Thm"]
TARGET = "yTi"


def spec(house: int, seed: int) -> JobSpec:
    return JobSpec(dataset="buildings", dataset_params={"house": house}, model="mlr", split="chronological",
                   split_params={"test_last_h": HOLDOUT_H}, targets=[TARGET], seed=seed, storage=None,
                   progress=False)


def flaml(recording, fold, seconds: float, seed: int) -> dict | None:
    """FLAML's held-out RMSE (K) on the raw inputs and with the target lagged by each horizon; None without it."""
    if not flaml_baseline.available():
        return None
    raw = recording.data[INPUTS].to_numpy(float)
    y = recording.data[TARGET].to_numpy(float)
    steps = {h: horizons.steps(h, recording.sampling_interval_s) for h in HORIZONS_H}
    variants = {"raw": raw, **{f"+lag{h}h": np.column_stack([raw, np.concatenate([np.full(k, y[0]), y[:-k]])])
                               for h, k in steps.items()}}
    return {name: rmse(flaml_baseline.fit_predict(X[fold.train], y[fold.train], X[fold.test],
                                                  seconds / len(variants), seed), y[fold.test])
            for name, X in variants.items()}


def run_house(house: int, budget: int, families: list[str], seed: int, greybox: dict | None) -> dict:
    sp = spec(house, seed)
    recording = registry.create("dataset", "buildings", house=house)
    (fold,) = splits.make_split(sp.split, seed=seed, **sp.split_params).folds(recording)
    started = time.perf_counter()
    result = automl_job.run(sp, Settings(budget_fits=budget, families=families), recording=recording)
    wall = time.perf_counter() - started
    by_h = horizons.scores(result.job, HORIZONS_H)
    cols = list(by_h.columns)
    row = {"house": house, "automl_wall_s": wall, "chosen": result.job.spec.model,
           "automl": {who: dict(zip(("one_step", "24h"), by_h.loc[who, cols].tolist())) for who in by_h.index},
           "flaml": flaml(recording, fold, wall, seed)}
    if greybox:
        g = next((h for h in greybox.get("houses", []) if h["house"] == f"blg_{house}"), None)
        if g:
            row["greybox"] = {"selected": g["selected"], "one_step": g["rmse1_selected"], "24h": g["rmse24_selected"],
                              "ti_one_step": g["rmse1_ti"], "ti_24h": g["rmse24_ti"]}
    return row


def table(rows: list[dict]) -> str:
    lines = ["| house | horizon | automl (chosen) | persistence | FLAML raw | FLAML +lag | grey-box selected | "
             "grey-box Ti |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        model = next(k for k in r["automl"] if k.startswith("model:"))
        for h, key in (("one step", "one_step"), ("24 h", "24h")):
            fl = r["flaml"] or {}
            lag = fl.get("+lag0h" if key == "one_step" else "+lag24h")
            g = r.get("greybox") or {}
            cells = [f"{r['automl'][model][key]:.3f} ({model[7:]})",
                     _k(r["automl"].get("persistence", {}).get(key)), _k(fl.get("raw")), _k(lag),
                     _k(g.get(key)) + (f" ({g['selected']})" if g else ""), _k(g.get(f"ti_{key}"))]
            lines.append(f"| blg_{r['house']} | {h} | " + " | ".join(cells) + " |")
    lines.append("RMSE in K on the last two weeks; automl and FLAML raw read inputs only (the same at both horizons)")
    return "\n".join(lines)


def _k(v) -> str:
    return "—" if v is None else f"{v:.3f}"


def main(args) -> None:
    greybox = json.loads(Path(args.greybox_json).read_text(encoding="utf-8")) if args.greybox_json else None
    rows = []
    for house in args.houses or HOUSES:
        rows.append(run_house(house, args.building_budget, args.building_families or FAMILIES, args.seed, greybox))
        print(f"blg_{house}: automl {rows[-1]['chosen']} in {rows[-1]['automl_wall_s']:.0f} s", flush=True)
    print(table(rows))
    if args.building_json:
        Path(args.building_json).write_text(json.dumps(rows, indent=1, default=float), encoding="utf-8")
