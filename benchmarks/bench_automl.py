"""AutoML benchmark: ``thermodrift automl`` against the best single family chosen with hindsight and FLAML.

Tasks (``--full``): FL_THERMAL (``--data``, the workbook) with ch3 as target under eight condition-held-out
splits (the project's 5000 rpm split, train t < 24.13 h and test 24.13–32.13 h; the 3500 rpm, 4500 rpm and
3750 rpm conditions held out, each training on every earlier condition; the final block of short runs,
500/1500/2500/4500 rpm, held out after training on t < 40.13 h; the first 2500 rpm run, the 3750 rpm run and the
5000 rpm run held out, each training on the other conditions of the first 40 h), and the four reference
machines (dataset ``reference_machines``: demo_spindle, turning_centre_s1, vmc_spindle_s2, motorized_spindle_s3;
their last working condition held out, every displacement channel), and sixteen machines that are not ours
(group ``indep``; its halves ``indep_first`` and ``indep_second``): recordings of the independent concealed-effect
generators (``benchmarks/independent``, no code shared with the library; ``fd`` a finite-volume machining centre,
``lumped`` a lumped network of another topology per seed), development seeds only (< 1000), four null cases and
four with a planted mechanism per generator, written as table + manifest and read back through the public file
format (dataset ``recording_file``); every drift channel, the last working condition holding at least 5 % of the
rows held out (the training part keeps every condition before it); group ``indep_sealed``, sixteen more of the
same shape from the generators' sealed seeds (from 8000), fixed before they were first run; ``indep_sealed2``,
sixteen more from 10000, fixed the same way and run once as a measurement. The default run is two
small reference machines with small budgets (under 10 minutes on 2 cores).

Per task:

* automl at its default budget (``--full``) and at three more budgets (fits): held-out RMSE (µm, mean over
  targets), wall time (s), the chosen pipeline;
* the best single family with hindsight: every family untuned on all sensors, plus (``--full``) 10 TPE trials
  of its own search space (networks at a ninth of their epochs), each scored on the held-out part; the best;
* FLAML (``pip install -e ".[compare]"``), given automl's wall time at the default budget on one core, per
  target, on the raw inputs and on automl's default feature stage (filtered temperatures and drive heat terms),
  its validation the last 25 % of the training rows (time order kept); left out, and said so, when FLAML is not
  installed.

Prints one table of held-out RMSE and the ratios automl / hindsight and automl / FLAML, and draws the
time-to-quality curves (held-out RMSE against wall time per budget) into ``--figure``. Results are cached per
task in ``--cache`` (JSON), so ``--full`` can run in pieces and resumes. Wall times depend on the machine's load.

Run::

    python benchmarks/bench_automl.py [--full] [--data ../shared/data/fl_thermal/data.xlsx] [--tasks NAME ...]
        [--budgets FITS ...] [--hindsight-trials N]
    python benchmarks/bench_automl.py --inner-table [--inner-tpe] --tasks NAME ...   # every candidate, held out too
    python benchmarks/bench_automl.py --rules --tasks NAME ...   # final-choice rules replayed on those predictions
    python benchmarks/bench_automl.py --buildings [--greybox-json FILE]   # the houses: automl, FLAML, grey-box
    python benchmarks/bench_automl.py --n-jobs [--tasks fl_5000rpm] [--budget FITS]   # n_jobs 1 vs the cores

``--budgets`` replaces the set's budgets (the default budget is always run), ``--hindsight-trials`` its TPE
trials per family for the hindsight best and ``--hindsight-families`` the families tried for it, so a piece of
``--full`` fits a time slot; the cache file names them.
"""

from __future__ import annotations

import argparse
import json
import pickle
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from thermodrift.compensator.features import FeatureStage
from thermodrift.core import metrics, registry, splits, study
from thermodrift.core.automl import job as automl_job, space
from thermodrift.core.automl.search import Settings
from thermodrift.core.metrics import evaluate
from thermodrift.core.study import INPUT_ROLES, Job, JobSpec

sys.path.insert(0, str(Path(__file__).resolve().parent))
import flaml_baseline  # noqa: E402 - FLAML, the comparison (one home for both benchmarks)
import independent  # noqa: E402 - the independent generators next to this script (no code shared with the library)

FL = {"dataset": "fl_thermal", "targets": ["ch3(um)"]}
TASKS = {
    "fl_5000rpm": {**FL, "split": "time_window",
                   "split_params": {"train_end_h": 24.13, "test_start_h": 24.13, "test_end_h": 32.13}},
    "fl_3500rpm": {**FL, "split": "condition_holdout", "split_params": {"test_conditions": ["3500rpm"]}},
    "fl_4500rpm": {**FL, "split": "condition_holdout", "split_params": {"test_conditions": ["4500rpm"]}},
    "fl_final": {**FL, "split": "time_window", "split_params": {"train_end_h": 40.13, "test_start_h": 40.13}},
    "fl_3750rpm": {**FL, "split": "condition_holdout", "split_params": {"test_conditions": ["3750rpm"]}},
    **{f"fl_{c.split('_')[1]}_others40": {**FL, "split": "condition_holdout", "split_params": {
        "test_conditions": [c], "train_on": "others", "train_end_h": 40.13}}
       for c in ("c02_2500rpm", "c03_3750rpm", "c04_5000rpm")},
    **{m: {"dataset": m, "targets": None, "split": "condition_holdout", "split_params": {}}
       for m in ("demo_spindle", "turning_centre_s1", "vmc_spindle_s2", "motorized_spindle_s3")},
}
# machines that are not ours: (generator, development seed, planted mechanism or None, constant drivers), the
# development list (independent.case_list) in its order, two mechanisms and two nulls at a time, to each generator
# in turn, so that no programme repeats
INDEPENDENT = [("fd", 0, "ambient_coupling", False), ("fd", 1, "coolant_coupling", False), ("fd", 500, None, False),
               ("fd", 501, None, True), ("lumped", 2, "cutting_heat", False),
               ("lumped", 3, "speed_dependent_convection", False), ("lumped", 502, None, False),
               ("lumped", 503, None, True),
               ("fd", 4, "bearing_heat_law", False), ("fd", 5, "preload_feedback", False), ("fd", 504, None, False),
               ("fd", 505, None, True), ("lumped", 6, "sensor_lag", False), ("lumped", 7, "centrifugal_growth", False),
               ("lumped", 506, None, False), ("lumped", 507, None, True)]


def _sealed_range(base: int) -> tuple[list, list]:
    """(planted, nulls) of the generators' sealed range from ``base``: one case per mechanism and eight nulls."""
    cases = independent.case_list(sealed=True, per_mechanism=1, nulls=8, base=base)
    return [c for c in cases if c[1]], [c for c in cases if not c[1]]


def _task_name(generator: str, seed: int, hidden: str | None) -> str:
    return f"{generator}_{hidden or 'null'}_{seed}"


# a sealed set of the same shape, fixed before it was first run and run once with the final rule of the change that
# added it: the sealed range from 8000 (independent.case_list), fd the first four mechanisms and four nulls, lumped
# the next four and four nulls
_planted, _nulls = _sealed_range(8000)
SEALED = [("fd", *c) for c in _planted[:4] + _nulls[:4]] + [("lumped", *c) for c in _planted[4:8] + _nulls[4:]]
# a second one, fixed the same way before it was first run (a measurement of the search as it stood, nothing
# chosen on it): the range from 10000, fd the mechanisms lumped had above, lumped the other three and the first
_planted, _nulls = _sealed_range(10000)
SEALED2 = [("fd", *c) for c in _planted[4:8] + _nulls[:4]] + [("lumped", *c) for c in _planted[8:11] + _planted[:1]
                                                                + _nulls[4:]]
TASKS.update({_task_name(g, s, h): {"generator": g, "case_seed": s, "hidden": h, "constant_drivers": c,
                                     "dataset": "recording_file", "targets": None, "split": "condition_holdout"}
              for g, s, h, c in INDEPENDENT + SEALED + SEALED2})
_machines = [n for n, t in TASKS.items() if "generator" in t]
GROUPS = {"indep": [n for n in _machines if TASKS[n]["case_seed"] < independent.SEALED_FROM],
          "indep_sealed": [_task_name(g, s, h) for g, s, h, _ in SEALED],
          "indep_sealed2": [_task_name(g, s, h) for g, s, h, _ in SEALED2]}
GROUPS["indep_first"], GROUPS["indep_second"] = GROUPS["indep"][:8], GROUPS["indep"][8:]
QUICK = {"tasks": ["demo_spindle", "motorized_spindle_s3"], "budgets": [12, 24, 48], "default": 48,
         "families": ["mlr", "mnr", "transfer_function", "bp"], "tpe": 0}
FULL = {"budgets": [30, 60, 240], "default": Settings().budget_fits, "families": None, "tpe": 10}


def independent_task(task: dict, folder: Path) -> tuple[dict, dict]:
    """An independent generator's recording written to ``folder`` as table + manifest (the public file format):
    the dataset parameters that read it back, and the split parameters holding out its last working condition
    with at least ``inner.MIN_SHARE`` of the rows (a programme's final minutes can be one short speed step, too
    short to score on; the inner folds ignore such a condition for the same reason)."""
    from thermodrift.core.automl import folds as inner
    from thermodrift.core.recording import load_recording

    gen = independent.make_case(task["case_seed"], task["hidden"], constant_drivers=task["constant_drivers"],
                                generator=task["generator"])
    table, manifest = gen.write(folder)
    recording = load_recording(table, manifest)
    labels = recording.conditions().to_numpy()
    held = next(c for c in reversed(list(dict.fromkeys(labels)))
                if np.count_nonzero(labels == c) >= inner.MIN_SHARE * len(labels))
    (fold,) = splits.make_split("condition_holdout", test_conditions=[held]).folds(recording)
    if len(inner.inner_folds(recording, fold.train)) < 2:  # the rule needs noise across folds to act on
        raise ValueError(f"{gen.name}: the training part before {held} gives fewer than two inner folds")
    return {"table": str(table), "manifest": str(manifest)}, {"test_conditions": [held]}


def spec_of(task: dict, seed: int, data: str | None, cache: Path = Path(".bench_cache/automl")) -> JobSpec:
    params = {"path": data} if task["dataset"] == "fl_thermal" and data else {}
    split_params = task.get("split_params", {})
    if "generator" in task:
        params, split_params = independent_task(task, cache / "recordings")
    return JobSpec(dataset=task["dataset"], dataset_params=params, model="mlr", split=task["split"],
                   split_params=split_params, targets=task["targets"], seed=seed, storage=None,
                   progress=False)


def held_out(job) -> dict:
    return {"rmse": job.summary_metrics("model")["rmse"],
            "per_target": {t: job.summary_metrics("model", t)["rmse"] for t in job.targets},
            "mlr": job.summary_metrics("mlr")["rmse"], "persistence": job.summary_metrics("persistence")["rmse"]}


def run_automl(spec: JobSpec, recording, budget: int, families, board: Path | None = None) -> dict:
    """automl at ``budget`` fits: held-out RMSE, wall time, the choice; its leaderboard into ``board`` (CSV)."""
    started, cpu = time.perf_counter(), time.process_time()
    result = automl_job.run(spec, Settings(budget_fits=budget, families=families), recording=recording)
    if board is not None:
        result.leaderboard.to_csv(board, index=False)
    chosen = result.search.ensemble or result.search.best.candidate.params
    return {"budget": budget, "wall_s": time.perf_counter() - started, "cpu_s": time.process_time() - cpu,
            **held_out(result.job),
            "chosen": result.job.spec.model, "label": json.dumps(chosen, default=str)[:300],
            "inner_score": result.job.valid_rmse}


def hindsight(spec: JobSpec, recording, families, tpe: int) -> dict:
    """Every family untuned (and with ``tpe`` trials), scored on the held-out part; the best of them."""
    out = {}
    for fam in space.families(only=families):
        params = {}
        if fam.network:
            params = space.at_rung(space.Candidate({"model": fam.name, "model_params": {}}), 1, fam, 3)[
                "model_params"]
        for trials in ([0, tpe] if tpe else [0]):
            key = f"{fam.name}{'' if not trials else f' tpe{trials}'}"
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    job = Job(JobSpec(**{**spec.__dict__, "model": fam.name, "model_params": params,
                                         "selector": "all", "n_trials": trials})).run(recording)
                out[key] = held_out(job)["rmse"]
            except Exception as exc:  # a family that cannot run on this task is noted, the others go on
                out[key] = float("nan")
                print(f"  hindsight {key}: failed ({type(exc).__name__}: {str(exc)[:120]})")
    finite = {k: v for k, v in out.items() if np.isfinite(v)}
    best = min(finite, key=finite.get)
    return {"best": best, "rmse": finite[best], "all": out}


def flaml_scores(spec: JobSpec, recording, seconds: float) -> dict | None:
    """FLAML on raw inputs and on the default feature stage, ``seconds`` in all, one core; None without FLAML."""
    if not flaml_baseline.available():
        return None
    (fold,) = splits.make_split(spec.split, seed=spec.seed, **spec.split_params).folds(recording)
    targets = study.targets_of(recording, spec.targets)
    inputs = study.input_columns(recording, (*INPUT_ROLES, "speed", "cutting_power"), targets)
    raw = recording.data[inputs].to_numpy(dtype=float)
    roles = {c: recording.channels[c].role for c in inputs}
    stage = FeatureStage.fit(raw[fold.train], inputs, roles, recording.time_s[fold.train],
                             space.DEFAULT_FEATURES["taus_s"], space.DEFAULT_FEATURES["powers"])
    variants = {"raw": raw[:, [i for i, c in enumerate(inputs) if roles[c] in INPUT_ROLES]],
                "features": stage.transform(raw[:, [inputs.index(c) for c in stage.inputs]])}
    out = {}
    for name, X in variants.items():
        pred = np.zeros((len(fold.test), len(targets)))
        for k, target in enumerate(targets):
            y = recording.data[target].to_numpy(dtype=float)
            pred[:, k] = flaml_baseline.fit_predict(X[fold.train], y[fold.train], X[fold.test],
                                                    seconds / (2 * len(targets)), spec.seed)
        out[name] = evaluate(recording.data[targets].iloc[fold.test], pred)["mean"]["rmse"]
    return out


def run_task(name: str, conf: dict, args) -> dict:
    task = TASKS[name]
    spec = spec_of(task, args.seed, args.data, args.cache)
    recording = registry.create("dataset", spec.dataset, **spec.dataset_params)
    budgets = sorted(set(conf["budgets"]) | {conf["default"]})
    runs = []
    for b in budgets:
        runs.append(run_automl(spec, recording, b, conf["families"],
                               args.cache / f"{name}-leaderboard-b{b}-s{args.seed}.csv"))
        r = runs[-1]
        print(f"  {name}: automl budget {b}: held-out RMSE {r['rmse']:.3f} µm in {r['wall_s']:.0f} s "
              f"({r['cpu_s']:.0f} s of CPU; {r['chosen']})", flush=True)
    default = next(r for r in runs if r["budget"] == conf["default"])
    best = hindsight(spec, recording, args.hindsight_families or conf["families"], conf["tpe"])
    print(f"  {name}: hindsight best {best['best']} {best['rmse']:.3f} µm", flush=True)
    flaml = flaml_scores(spec, recording, default["wall_s"])
    return {"task": name, "automl": runs, "default_budget": conf["default"], "hindsight": best, "flaml": flaml}


def task_folds(name: str, args):
    """Task ``name`` as the search splits it: (recording, outer fold, targets, inner folds)."""
    from thermodrift.core.automl import folds as inner

    spec = spec_of(TASKS[name], args.seed, args.data, args.cache)
    recording = registry.create("dataset", spec.dataset, **spec.dataset_params)
    (fold,) = splits.make_split(spec.split, seed=spec.seed, **spec.split_params).folds(recording)
    targets = study.targets_of(recording, spec.targets)
    return recording, fold, targets, inner.inner_folds(recording, fold.train, Settings().max_folds)


def inner_setup(name: str, args):
    """Task ``name`` as the search sees it: :func:`task_folds` and the inner folds' evaluator."""
    from thermodrift.core.automl.evaluate import Evaluator

    recording, fold, targets, folds = task_folds(name, args)
    return recording, fold, targets, folds, Evaluator(recording, fold.train, targets, folds, args.seed)


def score_candidate(cand, phase: str, recording, fold, targets, ev) -> dict:
    """One candidate's inner-fold RMSEs and predictions and its held-out prediction after the refit on the whole
    training part (the form ``--inner-table`` keeps and :func:`final_rules` replays)."""
    from thermodrift.core.study import predict_rows

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        e = ev.evaluate(cand.params, measure_costs=False)
        model = ev.pipeline(cand.params).fit(ev.X.iloc[fold.train], ev.y.iloc[fold.train])
        pred = predict_rows(model, ev.X, fold.test)
    return {"label": space.describe(cand.params), "params": cand.params, "phase": phase, "fold_rmse": e.fold_rmse,
            "score": e.score, "fold_pred": e.predictions, "pred": np.asarray(pred),
            "held_out": evaluate(recording.data[targets].iloc[fold.test], pred)["mean"]["rmse"]}


def inner_table(name: str, args) -> str:
    """Why a choice goes wrong: every portfolio candidate (networks aside; with ``--inner-tpe`` also the TPE
    candidates of the task's default-budget leaderboard) with its inner-fold RMSEs (µm), their (mean + worst) / 2
    and its held-out RMSE after the refit on the whole training part (µm)."""
    recording, fold, targets, folds, ev = inner_setup(name, args)
    fams = [f for f in space.families() if not f.network]
    saved = {"folds": [f.name for f in folds], "fold_truth": [t.to_numpy() for t in ev.truth],
             "truth": recording.data[targets].iloc[fold.test].to_numpy(), "candidates": []}
    lines = [f"{name}: inner folds " + "; ".join(f.name.removeprefix("inner: ") for f in folds),
             "| candidate | " + " | ".join(f"fold {k + 1}" for k in range(len(folds))) + " | inner score | held out |",
             "|---|" + "---:|" * (len(folds) + 2)]
    cands = [(cand, "portfolio") for cand in space.portfolio(fams, space.selectors())]
    board = args.cache / f"{name}-leaderboard-b{Settings().budget_fits}-s{args.seed}.csv"
    if args.inner_tpe and board.exists():  # the TPE candidates the default-budget search scored (cheap families)
        import pandas as pd
        rows = pd.read_csv(board)
        cands += [(space.Candidate(json.loads(r.params)), "tpe") for r in rows.itertuples()
                  if r.phase == "tpe" and r.status == "ok"]
    for cand, phase in cands:
        c = score_candidate(cand, phase, recording, fold, targets, ev)
        out = c.pop("held_out")
        saved["candidates"].append(c)
        lines.append(f"| {c['label']} | " + " | ".join(f"{r:.2f}" for r in c["fold_rmse"])
                     + f" | {c['score']:.2f} | {out:.2f} |")
        print(lines[-1], flush=True)
    args.cache.mkdir(parents=True, exist_ok=True)
    with open(args.cache / f"{name}-inner-s{args.seed}.pkl", "wb") as fh:  # to compare selection rules offline
        pickle.dump(saved, fh)
    return "\n".join(lines)


def final_rules(saved: dict, pool: int = Settings().ensemble_pool) -> dict:
    """Held-out RMSE (µm) and member count of the final-choice rules on one task's ``--inner-table --inner-tpe``
    predictions (networks aside), through :mod:`thermodrift.core.automl.search`'s own functions: TPE candidates
    eligible when they earn their place against the best a-priori one; ``one-SE inverse-MSE weights``: the
    search's rule (the average of :func:`~thermodrift.core.automl.search.one_se_set` with
    :func:`~thermodrift.core.automl.search.inverse_mse_weights`; with fewer than two members the greedy ensemble
    when it wins in and out of fold, else the best); ``one-SE flat``: the same set with equal weights (the rule
    before); ``best single``: the eligible candidate with the best inner score; ``one vote per family and input
    set``: the one-SE set keeping the best member per family and input set (equal weights); ``hindsight best
    candidate``: the best held out, which no rule can know."""
    from thermodrift.core.automl.evaluate import Evaluation
    from thermodrift.core.automl.folds import aggregate
    from thermodrift.core.automl.search import (Entry, diverse_pool, eligible, family_and_inputs, greedy_weights,
                                                inverse_mse_weights, one_se_set)

    truth, fold_truth = saved["truth"], saved["fold_truth"]

    def rmse(pred, y):  # RMSE (µm) per target, mean over targets
        return float(np.mean(metrics.rmse(pred, y, axis=0)))

    def inner_score(preds):
        return aggregate([rmse(p, y) for p, y in zip(preds, fold_truth)])

    entries = [Entry(i, space.Candidate(c["params"]), Evaluation(c["fold_rmse"], {}, c["score"], c["fold_pred"]),
                     phase=c["phase"]) for i, c in enumerate(saved["candidates"]) if np.isfinite(c["score"])]
    held_pred = {i: np.asarray(c["pred"]) for i, c in enumerate(saved["candidates"])}
    ok = sorted(eligible(entries, [e for e in entries if e.phase != "tpe"])[0], key=lambda e: (e.score, e.number))
    best = ok[0]

    def predictions(e):
        return e.evaluation.predictions

    def held(members):
        return rmse(sum(w * held_pred[e.number] for w, e in members), truth), len(members)

    def average(members):
        return held([(1 / len(members), e) for e, _ in members])

    # with one inner fold the search forms no one-SE set (no noise to estimate; :meth:`Search._hedge`)
    one_se = one_se_set(ok, best.evaluation.fold_rmse, predictions, pool) if len(fold_truth) >= 2 else []
    if len(one_se) >= 2:
        current = held(list(zip(inverse_mse_weights([e for e, _ in one_se]), (e for e, _ in one_se))))
    else:
        chosen = diverse_pool(ok, pool)
        weights = greedy_weights([predictions(e) for e in chosen], inner_score, lambda p, k: rmse(p, fold_truth[k]),
                                 best.score, Settings().ensemble_steps)[0] if len(chosen) >= 2 else None
        current = held([(w, e) for w, e in zip(weights, chosen) if w > 0] if weights is not None else [(1.0, best)])
    vote = one_se_set(ok, best.evaluation.fold_rmse, predictions, pool, key=family_and_inputs) if one_se else []
    return {"one-SE inverse-MSE weights": current, "one-SE flat": average(one_se) if len(one_se) >= 2 else current,
            "best single": held([(1.0, best)]),
            "one vote per family and input set": average(vote) if len(vote) >= 2 else current,
            "hindsight best candidate": min((held([(1.0, e)]) for e in entries), key=lambda x: x[0])}


def rules_table(names: list[str], args) -> str:
    """:func:`final_rules` per task, and the geometric mean of each rule's held-out RMSE over the search's rule's."""
    rows, ratios = [], {}
    for name in names:
        with open(args.cache / f"{name}-inner-s{args.seed}.pkl", "rb") as fh:
            r = final_rules(pickle.load(fh))
        rows.append((name, r))
        for rule, (v, _) in r.items():
            ratios.setdefault(rule, []).append(v / r["one-SE inverse-MSE weights"][0])
    rules = list(rows[0][1])
    lines = ["| task | " + " | ".join(f"{r} (µm, members)" for r in rules) + " |", "|---|" + "---:|" * len(rules)]
    lines += [f"| {n} | " + " | ".join(f"{v:.3f} ({k})" for v, k in r.values()) + " |" for n, r in rows]
    lines.append("| geometric mean / the search's rule | " + " | ".join(
        f"{np.exp(np.mean(np.log(ratios[r]))):.3f}" for r in rules) + " |")
    return "\n".join(lines)


def table(results: list[dict]) -> str:
    head = ("| task | automl RMSE (µm) | budget (fits) | wall s | hindsight best | its RMSE | automl / hindsight "
            "| FLAML raw | FLAML features | automl / FLAML best |")
    lines = [head, "|---|---:|---:|---:|---|---:|---:|---:|---:|---:|"]
    within = below = 0
    for r in results:
        d = next(a for a in r["automl"] if a["budget"] == r["default_budget"])
        ratio = d["rmse"] / r["hindsight"]["rmse"]
        within += ratio <= 1.2
        fl = r["flaml"]
        fbest = min(fl.values()) if fl else float("nan")
        below += bool(fl) and d["rmse"] < fbest
        lines.append(f"| {r['task']} | {d['rmse']:.3f} | {d['budget']} | {d['wall_s']:.0f} | {r['hindsight']['best']} "
                     f"| {r['hindsight']['rmse']:.3f} | {ratio:.2f} | "
                     + (f"{fl['raw']:.3f} | {fl['features']:.3f} | {d['rmse'] / fbest:.2f} |" if fl
                        else "not installed | not installed | — |"))
    lines.append(f"\nautoml within 1.2x of the hindsight best on {within} of {len(results)} tasks; below FLAML on "
                 f"{below} of {sum(bool(r['flaml']) for r in results)} tasks with FLAML")
    return "\n".join(lines)


def figure(results: list[dict], path: Path) -> None:
    """Time to quality: held-out RMSE (µm) per budget against the budget in fits (deterministic) and against wall
    time (load-dependent; points joined in budget order), with FLAML at automl's default-budget wall time (x). The
    RMSE itself, not its ratio to the hindsight best, so the curves do not depend on which families the hindsight
    run tried (``--hindsight-families``)."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter, ScalarFormatter

    fig = Figure(figsize=(11, 4))
    by_fits, by_time = fig.subplots(1, 2, sharey=True)
    for i, r in enumerate(results):
        runs = sorted(r["automl"], key=lambda a: a["budget"])
        rmse = [a["rmse"] for a in runs]
        by_fits.plot([a["budget"] for a in runs], rmse, "o-", color=f"C{i % 10}", label=r["task"])
        by_time.plot([a["wall_s"] for a in runs], rmse, "o-", color=f"C{i % 10}")
        if r["flaml"]:
            d = next(a for a in r["automl"] if a["budget"] == r["default_budget"])
            by_time.plot([d["wall_s"]], [min(r["flaml"].values())], "x", color=f"C{i % 10}", ms=8)
    for ax, label in ((by_fits, "budget (fits)"), (by_time, "wall time (s; o: automl, x: FLAML)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
        ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.yaxis.set_minor_formatter(FormatStrFormatter("%g"))
        ax.set_xlabel(label)
    by_fits.set_xticks(sorted({a["budget"] for r in results for a in r["automl"]}))
    by_fits.set_ylabel("held-out RMSE (µm)")
    fig.legend(fontsize=7, loc="center left", bbox_to_anchor=(0.91, 0.5))
    fig.savefig(path, dpi=110, bbox_inches="tight")


def parallel_table(name: str, args) -> str:
    """The default search on task ``name`` with ``automl.n_jobs`` 1 and with the default (the cores): wall time,
    CPU seconds of this process and of its worker processes (load-independent counts), and whether the
    leaderboards agree (timing columns aside) and the held-out RMSE is the same."""
    import os

    from thermodrift.core.automl.leaderboard import TIMING

    task = TASKS[name]
    spec = spec_of(task, args.seed, args.data, args.cache)
    recording = registry.create("dataset", spec.dataset, **spec.dataset_params)
    rows, boards = [], []
    for n_jobs in (1, None):
        settings = Settings(budget_fits=args.budget or Settings().budget_fits, n_jobs=n_jobs)
        before, started = os.times(), time.perf_counter()
        result = automl_job.run(spec, settings, recording=recording)
        wall, after = time.perf_counter() - started, os.times()
        boards.append(result.leaderboard.drop(columns=list(TIMING)))
        rows.append((settings.jobs(), wall, after.user + after.system - before.user - before.system,
                     after.children_user + after.children_system - before.children_user - before.children_system,
                     result.job.summary_metrics("model")["rmse"]))
    same = boards[0].equals(boards[1]) and rows[0][4] == rows[1][4]
    lines = [f"{name}: default search (budget {args.budget or Settings().budget_fits} fits), n_jobs 1 against the "
             "default; wall times depend on the machine's load",
             f"{'n_jobs':>7}{'wall s':>9}{'cpu s':>8}{'workers cpu s':>15}{'held-out µm':>13}"]
    lines += [f"{n:>7}{w:>9.1f}{c:>8.1f}{k:>15.1f}{r:>13.4f}" for n, w, c, k, r in rows]
    lines.append(f"wall ratio (default / n_jobs 1): {rows[1][1] / rows[0][1]:.2f}; leaderboards identical: "
                 f"{'yes' if same else 'NO'}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="every task, the default budget and three others")
    parser.add_argument("--tasks", nargs="*", help=f"a subset of {', '.join(TASKS)}, or the group indep (the "
                        "independent-generator machines; indep_first, indep_second: its halves), indep_sealed or "
                        "indep_sealed2")
    parser.add_argument("--data", default="../shared/data/fl_thermal/data.xlsx", help="the FL_THERMAL workbook")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cache", type=Path, default=Path(".bench_cache/automl"), help="per-task results (JSON)")
    parser.add_argument("--figure", type=Path, help="where the time-to-quality figure goes (default: <cache>/"
                        "automl_benchmark.png; the docs' figure is drawn with --figure docs/automl_benchmark.png)")
    parser.add_argument("--budgets", type=int, nargs="*", help="automl budgets (fits) besides the default one")
    parser.add_argument("--hindsight-trials", type=int, help="TPE trials per family for the hindsight best")
    parser.add_argument("--hindsight-families", nargs="*",
                        help="only these families for the hindsight best (e.g. the cheap ones with TPE trials)")
    parser.add_argument("--inner-table", action="store_true",
                        help="instead: each portfolio candidate's inner-fold and held-out RMSE per task (predictions "
                             "kept in --cache as <task>-inner-s<seed>.pkl)")
    parser.add_argument("--inner-tpe", action="store_true",
                        help="with --inner-table: also the TPE candidates of the task's default-budget leaderboard in "
                             "--cache (what the search's final choice drew from)")
    parser.add_argument("--rules", action="store_true",
                        help="instead: the held-out RMSE of final-choice rules from the --inner-table --inner-tpe "
                             "predictions in --cache")
    parser.add_argument("--buildings", action="store_true",
                        help="instead: the three real houses, automl against FLAML and the stochastic grey-box, one "
                             "step and 24 h ahead (benchmarks/automl_buildings.py)")
    parser.add_argument("--houses", type=int, nargs="*", help="with --buildings: only these houses (1, 2, 3)")
    parser.add_argument("--building-budget", type=int, default=24, help="with --buildings: automl's fits")
    parser.add_argument("--building-families", nargs="*", help="with --buildings: the families searched")
    parser.add_argument("--greybox-json", help="with --buildings: bench_greybox.py --houses --json, shown beside")
    parser.add_argument("--building-json", help="with --buildings: write the rows here")
    parser.add_argument("--n-jobs", action="store_true",
                        help="instead: the default search with automl.n_jobs 1 and the default (the cores) per task "
                             "(default fl_5000rpm): wall and CPU time, identical leaderboards")
    parser.add_argument("--budget", type=int, help="with --n-jobs: the budget (fits; default automl's default)")
    args = parser.parse_args()
    if args.n_jobs:
        for name in args.tasks or ["fl_5000rpm"]:
            print(parallel_table(name, args))
        return
    if args.buildings:
        import automl_buildings

        automl_buildings.main(args)
        return
    if args.tasks:
        args.tasks = [n for t in args.tasks for n in GROUPS.get(t, [t])]
    if args.inner_table:
        for name in args.tasks or QUICK["tasks"]:
            print(inner_table(name, args))
        return
    if args.rules:
        print(rules_table(args.tasks or QUICK["tasks"], args))
        return
    conf = dict(FULL if args.full else QUICK)
    if args.budgets is not None:
        conf["budgets"] = args.budgets
    if args.hindsight_trials is not None:
        conf["tpe"] = args.hindsight_trials
    tag = "full" if args.full else "quick"
    if args.budgets is not None or args.hindsight_trials is not None:
        tag += f"-b{'_'.join(map(str, sorted(set(conf['budgets']))))}-t{conf['tpe']}"
    if args.hindsight_families:
        tag += "-h" + "_".join(sorted(args.hindsight_families))
    names = args.tasks or (list(TASKS) if args.full else QUICK["tasks"])
    unknown = [n for n in names if n not in TASKS]
    if unknown:
        raise SystemExit(f"bench_automl: unknown task(s) {unknown}; choose from {', '.join(TASKS)}")
    args.cache.mkdir(parents=True, exist_ok=True)
    results = []
    for name in names:
        path = args.cache / f"{name}-{tag}-s{args.seed}.json"
        if path.exists():
            print(f"{name}: cached in {path}")
            results.append(json.loads(path.read_text(encoding="utf-8")))
            continue
        print(f"{name}: running", flush=True)
        results.append(run_task(name, conf, args))
        path.write_text(json.dumps(results[-1], indent=1, default=float), encoding="utf-8")
    print(table(results))
    args.figure = args.figure or args.cache / "automl_benchmark.png"
    args.figure.parent.mkdir(parents=True, exist_ok=True)
    figure(results, args.figure)
    print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
