"""Sampler benchmark: our population samplers against Optuna's TPE, CMA-ES, GP and Random search.

Samplers (all built by ``registry.create("optimizer", name, seed=s[, n_trials=budget])`` with default settings,
population size N = 10): ours ``pso``, ``gwo``, ``fa``, ``rbmo``, ``rbmox``; baselines ``tpe``, ``cmaes``, ``gp``,
``random``. Three parts, every run an independent process-pool task (``--workers``, default 2):

* **BBOB** (``ioh``): a subset of the 24 noiseless functions, one or two per BBOB group -- separable f1 sphere,
  f3 Rastrigin; moderate conditioning f7 step ellipsoid, f8 Rosenbrock; high conditioning f10 rotated ellipsoid;
  multimodal with global structure f15 rotated Rastrigin; weak structure f20 Schwefel, f21 Gallagher 101,
  f23 Katsuura -- at D in ``--dims`` over the box [-5, 5]^D. Every sampler gets the same budget
  ``--budget-mult`` x N x D trials (a multiple of N; of 2N, one RBMO iteration, where the product is even).
  Seed s runs BBOB instance s + 1 for every sampler (paired runs). Regret is f(best) - f(optimum) after the
  last trial. GP spends 0.4-1 s of CPU per model-based trial (its acquisition search runs L-BFGS-B restarts
  one after another), 100 times the others' cost, so on BBOB it runs a capped budget (``--gp-budget`` trials,
  ``--gp-seeds`` seeds, at D in ``--gp-dims``: 2 and 5, since a 10-D run costs as much as the two others) and is
  compared with every sampler's best-so-far regret at that trial.
* **Domain task**: tuning the ``bp`` network on the ``demo_spindle`` reference recording (the tiny test
  recording where that dataset is missing); objective = validation RMSE (µm, mean over the displacement
  channels) on the fold a study validates on (``splits.inner_fold``: the last working condition held out). The
  search space is ``bp``'s own with deliberately aggressive ranges: lr_max up to 10, clip_norm up to 100,
  AdamW weight decay up to 3 and ReLU as well as tanh. AdamW bounds every step by the learning rate, so
  lr_max <= 1 at the default weight decay never diverged on this recording (0 of 96 probes over activation,
  depth, width, batch size and clip_norm 10-100); training diverges where lr_max x
  weight_decay > 2 (the decoupled decay factor 1 - lr wd flips sign and grows) and for ReLU from lr_max ~ 2.5
  up (the smallest diverged ReLU trial seen in these studies).
  A trial whose training raises ``DivergedError`` fails with user attr ``diverged``; they are counted. A study
  has ``--domain-budget`` trials (default 100 = 10 generations of N: RBMO runs 4 search/attack iterations and
  RBMO-X's cosine cycle, opposition restarts and final local search all act; at 50 trials two iterations run,
  RBMO-X is RBMO with small changes, and most diverged trials come from the random generation 0 that both
  share). Every sampler runs ``--domain-seeds`` seeds (default 10). RBMO-X and RBMO run ``--paired-domain-seeds``
  (default 30) and are compared seed by seed: diverged trials per run (Wilcoxon signed-rank test) and the IQR of
  the final RMSE (a bootstrap over seeds gives a 95% interval of the IQR difference); divergence is rare (under
  one trial per run), so fewer seeds cannot tell them apart. GP takes a minute per 50-trial run and its cost
  grows with every trial, so it runs ``--gp-domain-budget`` trials (default 50) and ``--gp-domain-seeds`` seeds
  (default 4); every sampler's best-so-far RMSE at that trial stands beside it.
* **Overhead**: milliseconds per ask (``study.ask`` + the suggestions + ``study.tell``, in-memory storage, D = 5)
  once the study holds 100 and 1000 finished trials. Each study is filled by running the sampler itself,
  since the population samplers and CMA-ES keep their state in the trials' attributes; GP is filled with
  random trials through ``add_trials`` (running it to 1000 trials would take hours), which it models alike.

Statistics: median and IQR of the final regret per (function, D, sampler); Friedman mean ranks of the cell
medians over the (function, D) cells, Wilcoxon signed-rank tests of every sampler against the best-ranked one
over those cells with Holm's correction; the share of cells where a sampler's median regret is below Random's.

Run ``python benchmarks/bench_samplers.py`` (11.2 min on 2 otherwise idle cores of an AMD EPYC; 33.6 min on 2
cores of a host that took 17-53% of the CPU; ``--quick`` for a smoke test, ``--parts domain`` for one part). It
prints the markdown report and writes it to ``--out`` with the command that made it at the top.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import os
import platform
import shlex
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

OURS = ("pso", "gwo", "fa", "rbmo", "rbmox")
PAIRED = ("rbmox", "rbmo")  # compared seed by seed on the domain task
PARTS = ("bbob", "domain", "overhead")
BASELINES = ("tpe", "cmaes", "gp", "random")
POPULATION_SIZE = 10  # the population samplers' default N; budgets are multiples of it
FUNCTIONS = {1: "sphere", 3: "Rastrigin", 7: "step ellipsoid", 8: "Rosenbrock", 10: "rot. ellipsoid",
             15: "rot. Rastrigin", 20: "Schwefel", 21: "Gallagher 101", 23: "Katsuura"}
BOX = (-5.0, 5.0)  # the BBOB search domain per coordinate
DOMAIN_EPOCHS = 60  # per bp trial; SGDR cycle ends inside it are where the trainer reads fitness
OVERHEAD_DIM = 5
OVERHEAD_REPEATS = {"gp": 3}  # asks timed per size; GP takes seconds per ask at 1000 trials
DEFAULT_OVERHEAD_REPEATS = 20


@dataclass(frozen=True)
class Config:
    """One benchmark size. Budgets in trials; ``functions`` are BBOB function ids."""

    seeds: int
    dims: tuple[int, ...]
    budget_mult: int
    functions: tuple[int, ...]
    gp_budget: int
    gp_seeds: int
    gp_dims: tuple[int, ...]
    domain_budget: int
    domain_seeds: int
    paired_domain_seeds: int
    gp_domain_budget: int
    gp_domain_seeds: int
    domain_epochs: int
    overhead_sizes: tuple[int, ...]
    workers: int
    parts: tuple[str, ...] = PARTS

    def budget(self, dim: int) -> int:
        return self.budget_mult * POPULATION_SIZE * dim


# ------------------------------------------------------------------------------------------------ the runs
def _quiet_worker() -> None:
    """One torch and BLAS thread per worker process: the workers, not the libraries, use the cores."""
    import optuna
    import torch

    torch.set_num_threads(1)
    optuna.logging.set_verbosity(optuna.logging.ERROR)


def make_sampler(name: str, seed: int, n_trials: int):
    """The registered sampler ``name``; ``n_trials`` only goes to factories that take a budget."""
    from thermodrift.core import registry

    return registry.create_sampler(name, seed=seed, n_trials=n_trials)


def bbob_run(sampler: str, fid: int, dim: int, seed: int, budget: int) -> dict[str, Any]:
    """One study on BBOB function ``fid``, instance ``seed + 1``; returns the best-so-far regret per trial."""
    import ioh
    import optuna

    problem = ioh.get_problem(fid, instance=seed + 1, dimension=dim, problem_class=ioh.ProblemClass.BBOB)
    names = [f"x{i}" for i in range(dim)]

    def objective(trial: optuna.Trial) -> float:
        return float(problem([trial.suggest_float(n, *BOX) for n in names]))

    study = optuna.create_study(sampler=make_sampler(sampler, seed, budget))
    study.optimize(objective, n_trials=budget)
    regret = np.array([t.value for t in study.trials]) - problem.optimum.y
    return {"part": "bbob", "sampler": sampler, "fid": fid, "dim": dim, "seed": seed,
            "curve": np.minimum.accumulate(regret).tolist()}


@lru_cache(maxsize=1)
def _domain_data():
    """(X °C, y µm, train rows, validation rows, dataset name) of the fixed recording, once per process."""
    from thermodrift.core import registry, splits

    if "demo_spindle" in registry.names("dataset"):
        name, recording = "demo_spindle(seed=0)", registry.create("dataset", "demo_spindle", seed=0)
    else:
        from thermodrift.testing.data import tiny_recording

        name, recording = "tiny_recording(seed=0)", tiny_recording(seed=0)
    fold = splits.inner_fold(recording)
    return recording.temperatures, recording.displacements, fold.train, fold.test, name


def domain_space() -> dict[str, dict[str, Any]]:
    """``bp``'s search space with the aggressive ranges that make divergence possible (module docstring)."""
    from thermodrift.core import registry

    space = registry.get("model", "bp").factory.search_space()
    space.update(trainer__lr_max={"type": "float", "low": 1e-4, "high": 10.0, "log": True},
                 trainer__clip_norm={"type": "float", "low": 0.1, "high": 100.0, "log": True},
                 trainer__weight_decay={"type": "float", "low": 1e-5, "high": 3.0, "log": True},
                 activation={"type": "categorical", "choices": ["tanh", "relu"]})
    return space


def domain_run(sampler: str, seed: int, budget: int, epochs: int) -> dict[str, Any]:
    """One study tuning ``bp``; returns the best-so-far validation RMSE (µm) per trial and diverged trials."""
    import optuna
    from thermodrift.core import metrics, registry, search_space
    from thermodrift.core.training import DivergedError

    X, y, train, val, _ = _domain_data()
    space = domain_space()

    def objective(trial: optuna.Trial) -> float:
        model = registry.create("model", "bp", trainer__epochs=epochs, **search_space.suggest(trial, space))
        try:
            model.fit(X.iloc[train], y.iloc[train])
        except DivergedError:
            trial.set_user_attr("diverged", True)
            raise
        return metrics.evaluate(y.iloc[val], model.predict(X.iloc[val]))["mean"]["rmse"]

    study = optuna.create_study(sampler=make_sampler(sampler, seed, budget))
    study.optimize(objective, n_trials=budget, catch=(DivergedError,))
    values = [t.value if t.state == optuna.trial.TrialState.COMPLETE else math.inf for t in study.trials]
    return {"part": "domain", "sampler": sampler, "seed": seed, "curve": np.minimum.accumulate(values).tolist(),
            "diverged": sum(bool(t.user_attrs.get("diverged")) for t in study.trials),
            "failed": sum(t.state == optuna.trial.TrialState.FAIL for t in study.trials)}


def overhead_run(sampler: str, sizes: tuple[int, ...]) -> dict[str, Any]:
    """Median CPU and wall ms per ask + suggest + tell on a 5-D sphere once the study holds ``sizes`` trials."""
    import optuna
    from optuna.distributions import FloatDistribution

    space = {f"x{i}": FloatDistribution(*BOX) for i in range(OVERHEAD_DIM)}
    repeats = OVERHEAD_REPEATS.get(sampler, DEFAULT_OVERHEAD_REPEATS)
    study = optuna.create_study(sampler=make_sampler(sampler, 0, max(sizes) + repeats))
    rng = np.random.default_rng(0)

    def step() -> tuple[float, float]:
        """(CPU s, wall s) of one ask + tell; CPU time does not count waiting for a core on a shared machine."""
        cpu, wall = time.process_time(), time.perf_counter()
        trial = study.ask(space)  # fixed distributions: ask suggests them, which runs the sampler
        study.tell(trial, float(np.sum(np.square(list(trial.params.values())))))
        return time.process_time() - cpu, time.perf_counter() - wall

    ms: dict[int, tuple[float, float]] = {}  # size -> median (CPU ms, wall ms)
    for size in sorted(sizes):
        missing = size - len(study.trials)
        if sampler == "gp":
            xs = rng.uniform(*BOX, size=(missing, OVERHEAD_DIM))
            study.add_trials([optuna.trial.create_trial(params=dict(zip(space, map(float, x))),
                                                        distributions=space, value=float(np.sum(x * x)))
                              for x in xs])
        else:
            for _ in range(missing):
                step()
        ms[size] = tuple(1e3 * np.median([step() for _ in range(repeats)], axis=0))
    return {"part": "overhead", "sampler": sampler, "ms": ms}


def _run(task: tuple[Callable[..., dict[str, Any]], tuple]) -> dict[str, Any]:
    """Run one task; add its wall time and this process's CPU time (s), the latter independent of load."""
    func, args = task
    wall, cpu = time.perf_counter(), time.process_time()
    result = func(*args)
    return {**result, "seconds": time.perf_counter() - wall, "cpu_seconds": time.process_time() - cpu}


def tasks(config: Config) -> list[tuple[Callable[..., dict[str, Any]], tuple]]:
    """Every independent run, the longest first so that the two workers finish together."""
    samplers = OURS + BASELINES
    jobs: list[tuple[float, Callable, tuple]] = []  # (cost class for the ordering, function, arguments)
    for fid in config.functions if "bbob" in config.parts else ():
        for dim in config.dims:
            for seed in range(config.seeds):
                for name in samplers:
                    if name == "gp":
                        if seed < config.gp_seeds and dim in config.gp_dims:
                            jobs.append((2, bbob_run, (name, fid, dim, seed, config.gp_budget)))
                    else:
                        budget = config.budget(dim)
                        jobs.append((budget * (3 if name == "tpe" else 1) / 1e4, bbob_run,
                                     (name, fid, dim, seed, budget)))
    for name in samplers if "domain" in config.parts else ():
        seeds, budget = config.domain_seeds, config.domain_budget
        if name in PAIRED:
            seeds = config.paired_domain_seeds
        elif name == "gp":
            seeds, budget = config.gp_domain_seeds, config.gp_domain_budget
        for seed in range(seeds):
            jobs.append((3 if name == "gp" else 1, domain_run, (name, seed, budget, config.domain_epochs)))
    for name in samplers if "overhead" in config.parts else ():
        jobs.append((4, overhead_run, (name, config.overhead_sizes)))
    jobs.sort(key=lambda job: -job[0])
    return [(func, args) for _, func, args in jobs]


def run_all(config: Config, progress: bool = True) -> list[dict[str, Any]]:
    from tqdm import tqdm

    todo = tasks(config)
    bar = tqdm(total=len(todo), desc="runs", disable=not progress, file=sys.stderr)
    results = []
    if config.workers == 1:
        _quiet_worker()
        for task in todo:
            results.append(_run(task))
            bar.update()
    else:
        with multiprocessing.get_context("spawn").Pool(config.workers, initializer=_quiet_worker) as pool:
            for result in pool.imap_unordered(_run, todo):
                results.append(result)
                bar.update()
    bar.close()
    return results


# ------------------------------------------------------------------------------------------------ statistics
def iqr(values) -> float:
    q1, q3 = np.percentile(values, [25, 75])
    return float(q3 - q1)


def holm(pvalues: dict[str, float]) -> dict[str, float]:
    """Holm-Bonferroni adjusted p-values (step-down, monotone)."""
    order = sorted(pvalues, key=pvalues.get)
    adjusted, running = {}, 0.0
    for i, key in enumerate(order):
        running = max(running, min(1.0, (len(order) - i) * pvalues[key]))
        adjusted[key] = running
    return adjusted


def rank_test(medians: dict[str, list[float]]) -> tuple[dict[str, float], str, dict[str, float], float]:
    """Friedman mean ranks over cells (rank 1 = lowest regret), the best sampler, Holm-adjusted Wilcoxon p-values
    of each other sampler against it, and Friedman's p-value. ``medians[sampler]`` lists one value per cell."""
    from scipy import stats

    names = list(medians)
    table = np.array([medians[n] for n in names]).T  # cells x samplers
    ranks = np.array([stats.rankdata(row) for row in table]).mean(axis=0)
    mean_ranks = dict(zip(names, map(float, ranks)))
    best = min(names, key=mean_ranks.get)
    friedman_p = float(stats.friedmanchisquare(*table.T).pvalue) if len(names) >= 3 and len(table) >= 2 else math.nan
    raw = {}
    for name in names:
        if name == best:
            continue
        diff = np.array(medians[name]) - np.array(medians[best])
        raw[name] = 1.0 if not np.any(diff) else float(stats.wilcoxon(medians[name], medians[best]).pvalue)
    return mean_ranks, best, holm(raw), friedman_p


def paired_comparison(new: list[dict[str, Any]], old: list[dict[str, Any]], label: tuple[str, str] = ("RBMO-X",
                      "RBMO"), resamples: int = 10_000) -> str:
    """RBMO-X against RBMO on the domain task, paired by seed: diverged trials per run (Wilcoxon signed-rank), the
    IQR of the final RMSE with a bootstrap 95% interval of the IQR difference (seeds resampled in pairs) and the
    median final RMSE (Wilcoxon signed-rank)."""
    from scipy import stats

    by_seed = {r["seed"]: r for r in old}
    # In seed order: runs finish in any order, and the bootstrap draws pairs by position.
    pairs = [(r, by_seed[r["seed"]]) for r in sorted(new, key=lambda r: r["seed"]) if r["seed"] in by_seed]
    div_new, div_old = (np.array([p[i]["diverged"] for p in pairs]) for i in (0, 1))
    fin_new, fin_old = (np.array([p[i]["curve"][-1] for p in pairs]) for i in (0, 1))
    p_div = 1.0 if np.all(div_new == div_old) else float(stats.wilcoxon(div_new, div_old).pvalue)
    p_fin = 1.0 if np.all(fin_new == fin_old) else float(stats.wilcoxon(fin_new, fin_old).pvalue)
    rng = np.random.default_rng(0)
    picks = rng.integers(len(pairs), size=(resamples, len(pairs)))
    diffs = [iqr(fin_new[i]) - iqr(fin_old[i]) for i in picks]
    low, high = np.percentile(diffs, [2.5, 97.5])
    return (f"{label[0]} vs {label[1]}, {len(pairs)} paired seeds: diverged trials {div_new.sum()} vs "
            f"{div_old.sum()} (runs with any: {int((div_new > 0).sum())} vs {int((div_old > 0).sum())}; Wilcoxon "
            f"p = {_fmt(p_div)}); IQR of the final RMSE {_fmt(iqr(fin_new))} vs {_fmt(iqr(fin_old))} µm, "
            f"difference {_fmt(iqr(fin_new) - iqr(fin_old))} µm (bootstrap 95% interval {_fmt(low)} to "
            f"{_fmt(high)}); median {_fmt(float(np.median(fin_new)))} vs {_fmt(float(np.median(fin_old)))} µm "
            f"(Wilcoxon p = {_fmt(p_fin)}).\n")


def _cpu_model() -> str:
    """The processor's model name (Linux: /proc/cpuinfo), else its architecture."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as info:
            return next(line.split(":", 1)[1].strip() for line in info if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.machine()


def _fmt(x: float) -> str:
    return "inf" if not math.isfinite(x) else f"{x:.3g}" if x == 0 or 1e-3 <= abs(x) < 1e4 else f"{x:.2e}"


def report(config: Config, results: list[dict[str, Any]], command: str, seconds: float,
           load: tuple[float, float]) -> str:
    """The markdown report: what ran and how long, then the sections of the parts that ran."""
    from importlib.metadata import version

    import optuna
    import torch

    out = [f"# Sampler benchmark\n\nGenerated by `{command}`\n",
           (f"{len(results)} runs in {seconds / 60:.1f} min on {config.workers} worker processes "
           f"({os.cpu_count()} cores; load average {load[0]:.1f} at start, {load[1]:.1f} at end; the machine is "
           f"shared, so times are upper bounds). Python {platform.python_version()}, optuna {optuna.__version__}, "
           f"ioh {version('ioh')}, torch {torch.__version__}, numpy {np.__version__}. CPU: {_cpu_model()}, torch "
           f"kernels {torch.backends.cpu.get_cpu_capability()}; torch's results (the domain task, GP) repeat exactly "
           f"for a seed on the same kind of CPU, not across instruction sets.\n"),
           f"Parts: {', '.join(config.parts)}. Budgets: N = {POPULATION_SIZE}"]
    if "bbob" in config.parts:
        out[-1] += (f"; {config.budget_mult}·N·D trials per BBOB study "
                    f"({', '.join(f'D={d}: {config.budget(d)}' for d in config.dims)}), {config.seeds} seeds "
                    f"(seed s = BBOB instance s+1 for every sampler), GP: first {config.gp_budget} trials "
                    f"({config.gp_seeds} seeds, D={','.join(map(str, config.gp_dims))}) only, see its own table")
    if "domain" in config.parts:
        out[-1] += (f"; domain task: {config.domain_budget} trials, {config.domain_seeds} seeds "
                    f"({' and '.join(PAIRED)} {config.paired_domain_seeds}; GP {config.gp_domain_budget} trials, "
                    f"{config.gp_domain_seeds} seeds)")
    out[-1] += ". Defaults of every sampler; see the script's docstring for the protocol.\n"
    for section in (bbob_sections, domain_section, overhead_section, runtime_section):
        out += section(config, results)
    return "\n".join(out) + "\n"


def bbob_sections(config: Config, results: list[dict[str, Any]]) -> list[str]:
    """Final regret per cell, Friedman ranks, and every sampler at GP's capped budget."""
    samplers = [s for s in OURS + BASELINES if s != "gp"]
    bbob = defaultdict(dict)  # (fid, dim) -> sampler -> [curve per seed]
    for r in results:
        if r["part"] == "bbob":
            bbob[(r["fid"], r["dim"])].setdefault(r["sampler"], []).append((r["seed"], r["curve"]))
    cells = sorted(bbob)
    for cell in cells:
        for name in bbob[cell]:
            bbob[cell][name] = [c for _, c in sorted(bbob[cell][name])]
    if not cells:
        return []
    out = ["## Final regret on BBOB: median (IQR) over seeds\n"]
    out.append("| function | D | " + " | ".join(samplers) + " |")
    out.append("|---|---|" + "---|" * len(samplers))
    medians: dict[str, list[float]] = {s: [] for s in samplers}
    for fid, dim in cells:
        row = []
        for s in samplers:
            finals = [c[-1] for c in bbob[(fid, dim)][s]]
            medians[s].append(float(np.median(finals)))
            row.append(f"{_fmt(float(np.median(finals)))} ({_fmt(iqr(finals))})")
        out.append(f"| f{fid} {FUNCTIONS.get(fid, '')} | {dim} | " + " | ".join(row) + " |")

    # ranks
    mean_ranks, best, adjusted, friedman_p = rank_test(medians)
    out.append(f"\n## Friedman mean ranks over {len(cells)} (function, D) cells\n")
    out.append(f"Rank 1 = lowest median regret in a cell. Friedman test p = {_fmt(friedman_p)}. Wilcoxon "
               f"signed-rank test of each sampler's cell medians against the best-ranked ({best}), Holm-adjusted.\n")
    out.append("| sampler | mean rank | Holm p vs best | beats Random's median (cells) |")
    out.append("|---|---|---|---|")
    for s in sorted(samplers, key=mean_ranks.get):
        wins = sum(a < b for a, b in zip(medians[s], medians["random"]))
        share = "" if s == "random" else f"{wins}/{len(cells)} ({100 * wins / len(cells):.0f}%)"
        p = "—" if s == best else _fmt(adjusted[s])
        out.append(f"| {s} | {mean_ranks[s]:.2f} | {p} | {share} |")

    # GP at its capped budget
    gp_cells = [cell for cell in cells if "gp" in bbob[cell]]
    if gp_cells:
        cap, n_gp = config.gp_budget, config.gp_seeds
        out.append(f"\n## At GP's budget: median regret after {cap} trials, seeds 0–{n_gp - 1}\n")
        out.append("Every sampler's best-so-far regret at trial "
                   f"{cap} of the same runs (the population samplers' schedules still assume the full budget).\n")
        names = list(OURS + BASELINES)
        out.append("| function | D | " + " | ".join(names) + " |")
        out.append("|---|---|" + "---|" * len(names))
        at_cap: dict[str, list[float]] = {s: [] for s in names}
        for cell in gp_cells:
            row = []
            for s in names:
                value = float(np.median([c[cap - 1] for c in bbob[cell][s][:n_gp]]))
                at_cap[s].append(value)
                row.append(_fmt(value))
            out.append(f"| f{cell[0]} {FUNCTIONS.get(cell[0], '')} | {cell[1]} | " + " | ".join(row) + " |")
        ranks_cap, best_cap, adj_cap, p_cap = rank_test(at_cap)
        out.append(f"\nMean ranks at trial {cap} (Friedman p = {_fmt(p_cap)}; Holm-adjusted Wilcoxon vs "
                   f"{best_cap}): " + ", ".join(
                       f"{s} {ranks_cap[s]:.2f}" + ("" if s == best_cap else f" (p {_fmt(adj_cap[s])})")
                       for s in sorted(names, key=ranks_cap.get)) + ".")
        gp_secs = [r["seconds"] for r in results if r["part"] == "bbob" and r["sampler"] == "gp"]
        out.append(f"GP took {np.median(gp_secs):.1f} s per {cap}-trial run (median; max {max(gp_secs):.1f} s).\n")
    return out


def domain_section(config: Config, results: list[dict[str, Any]]) -> list[str]:
    """The domain task's table and the paired RBMO-X vs RBMO comparison."""
    domain = defaultdict(list)
    for r in results:
        if r["part"] == "domain":
            domain[r["sampler"]].append(r)
    if not domain:
        return []
    out = [f"\n## Domain task: tuning `bp` on {_domain_data()[4]}\n"]
    cap = config.gp_domain_budget
    out.append(f"Validation RMSE (µm) of the best trial after the run's trials ({config.domain_epochs} epochs "
               f"each), over the sampler's seeds 0, 1, ...; `at {cap}` is the best-so-far after trial {cap} of "
               "the same runs (GP's budget; the population samplers' schedules still assume the full budget). "
               "Diverged = trials whose training raised DivergedError (failed trials).\n")
    out.append(f"| sampler | seeds | trials | median RMSE µm | IQR µm | best / worst µm | median at {cap} µm | "
               "diverged trials (total) | diverged per run (mean, max) | s per run |")
    out.append("|---|---|---|---|---|---|---|---|---|---|")
    for s in OURS + BASELINES:
        runs = domain.get(s)
        if not runs:
            continue
        finals = [r["curve"][-1] for r in runs]
        div = [r["diverged"] for r in runs]
        out.append(f"| {s} | {len(runs)} | {len(runs[0]['curve'])} | {_fmt(float(np.median(finals)))} | "
                   f"{_fmt(iqr(finals))} | {_fmt(min(finals))} / {_fmt(max(finals))} | "
                   f"{_fmt(float(np.median([r['curve'][cap - 1] for r in runs])))} | {sum(div)} | "
                   f"{np.mean(div):.2f}, {max(div)} | {np.median([r['seconds'] for r in runs]):.1f} |")
    if all(name in domain for name in PAIRED):
        out.append("\n" + paired_comparison(*(domain[name] for name in PAIRED)))
    return out


def overhead_section(config: Config, results: list[dict[str, Any]]) -> list[str]:
    """Milliseconds per ask at each study size."""
    over = {r["sampler"]: r["ms"] for r in results if r["part"] == "overhead"}
    if not over:
        return []
    sizes = sorted(config.overhead_sizes)
    out = [f"\n## Sampler overhead: ms per ask (ask + {OVERHEAD_DIM} suggestions + tell, in-memory storage)\n"]
    out.append("CPU ms (wall ms in brackets): median over the asks that follow a study of the given size, "
               "timed while the other worker ran, so wall time includes waiting for a core; GP's study is "
               "filled with random trials. Random's row is Optuna's own cost per trial.\n")
    out.append("| sampler | " + " | ".join(f"{n} trials" for n in sizes) + " |")
    out.append("|---|" + "---|" * len(sizes))
    for s in OURS + BASELINES:
        if s in over:
            out.append(f"| {s} | " + " | ".join(f"{over[s][n][0]:.2f} ({over[s][n][1]:.2f})" for n in sizes)
                       + " |")
    return out


def runtime_section(config: Config, results: list[dict[str, Any]]) -> list[str]:
    """Worker wall and CPU seconds per part and sampler."""
    wall, cpu = defaultdict(float), defaultdict(float)
    for r in results:
        wall[(r["part"], r["sampler"])] += r["seconds"]
        cpu[(r["part"], r["sampler"])] += r["cpu_seconds"]
    parts = [p for p in PARTS if any(k[0] == p for k in wall)]
    total_cpu = sum(cpu.values())
    out = ["\n## Run time: worker seconds per part and sampler, wall / CPU\n"]
    out.append(f"CPU time is what the runs cost without the other load: {total_cpu / 60:.1f} CPU-minutes in all, "
               f"{total_cpu / 60 / config.workers:.1f} min of wall time on {config.workers} idle cores.\n")
    out.append("| sampler | " + " | ".join(parts) + " |")
    out.append("|---|" + "---|" * len(parts))
    for s in OURS + BASELINES:
        out.append(f"| {s} | " + " | ".join(f"{wall[(p, s)]:.0f} / {cpu[(p, s)]:.0f}" for p in parts) + " |")
    return out


# ------------------------------------------------------------------------------------------------ command line
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="tiny sizes for a smoke test (seconds)")
    parser.add_argument("--seeds", type=int, help="seeds per BBOB cell and sampler (default 10)")
    parser.add_argument("--dims", help="comma-separated dimensions (default 2,5,10)")
    parser.add_argument("--budget-mult", type=int, help="BBOB budget = this x N x D trials (default 3)")
    parser.add_argument("--functions", help="comma-separated BBOB function ids (default: "
                        + ",".join(map(str, FUNCTIONS)) + ")")
    parser.add_argument("--gp-budget", type=int, help="GP's BBOB budget in trials (default 30)")
    parser.add_argument("--gp-seeds", type=int, help="seeds GP runs per BBOB cell (default 2)")
    parser.add_argument("--gp-dims", help="comma-separated dimensions GP runs on BBOB (default 2,5)")
    parser.add_argument("--domain-budget", type=int, help="trials per domain study (default 100 = N + 4.5 RBMO "
                        "iterations)")
    parser.add_argument("--domain-seeds", type=int, help="seeds of the domain task (default 10)")
    parser.add_argument("--paired-domain-seeds", type=int, help="seeds RBMO-X and RBMO run on the domain task for "
                        "their paired comparison (default 30)")
    parser.add_argument("--gp-domain-budget", type=int, help="GP's domain budget in trials (default 50)")
    parser.add_argument("--gp-domain-seeds", type=int, help="seeds GP runs on the domain task (default 4)")
    parser.add_argument("--parts", default=",".join(PARTS), help="comma-separated parts to run (default: all of "
                        + ",".join(PARTS) + ")")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--out", default="docs/sampler_benchmark.md", help="markdown report path")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser.parse_args(argv)


def config_from(args: argparse.Namespace) -> Config:
    quick = args.quick
    defaults = {"seeds": 2 if quick else 10, "dims": "2" if quick else "2,5,10", "budget_mult": 1 if quick else 3,
                "functions": "1,3" if quick else ",".join(map(str, FUNCTIONS)), "gp_budget": 11 if quick else 30,
                "gp_seeds": 2, "gp_dims": "2" if quick else "2,5",
                "domain_budget": 10 if quick else 100, "domain_seeds": 2 if quick else 10,
                "paired_domain_seeds": 3 if quick else 30, "gp_domain_budget": 10 if quick else 50,
                "gp_domain_seeds": 2 if quick else 4}
    value = {k: getattr(args, k) if getattr(args, k) is not None else v for k, v in defaults.items()}
    config = Config(seeds=value["seeds"], dims=tuple(int(d) for d in str(value["dims"]).split(",")),
                    budget_mult=value["budget_mult"], functions=tuple(int(f) for f in str(value["functions"]).split(",")),
                    gp_budget=value["gp_budget"], gp_seeds=min(value["gp_seeds"], value["seeds"]),
                    gp_dims=tuple(int(d) for d in str(value["gp_dims"]).split(",")),
                    domain_budget=value["domain_budget"], domain_seeds=value["domain_seeds"],
                    paired_domain_seeds=value["paired_domain_seeds"], gp_domain_budget=value["gp_domain_budget"],
                    gp_domain_seeds=value["gp_domain_seeds"], domain_epochs=5 if quick else DOMAIN_EPOCHS,
                    overhead_sizes=(4, 8) if quick else (100, 1000), workers=args.workers,
                    parts=tuple(args.parts.split(",")))
    if not config.parts or set(config.parts) - set(PARTS):
        raise SystemExit(f"--parts takes a comma-separated subset of {','.join(PARTS)}, got {args.parts!r}")
    if min(config.seeds, config.domain_seeds, config.paired_domain_seeds, config.gp_domain_seeds) < 2:
        raise SystemExit("--seeds and every --*domain-seeds must be >= 2 (medians and IQRs over seeds)")
    if config.gp_domain_budget > config.domain_budget:
        raise SystemExit("--gp-domain-budget must not exceed --domain-budget (GP is compared at that trial)")
    if not set(config.gp_dims) <= set(config.dims):
        raise SystemExit("--gp-dims must be a subset of --dims")
    if config.gp_budget > min(config.budget(d) for d in config.dims):
        raise SystemExit("--gp-budget must not exceed the smallest BBOB budget (GP is compared at that trial)")
    return config


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    config = config_from(args)
    script = os.path.relpath(os.path.abspath(__file__))
    command = shlex.join(["python", script, *(sys.argv[1:] if argv is None else argv)])
    load_start = os.getloadavg()[0]
    started = time.perf_counter()
    results = run_all(config, progress=not args.no_progress)
    text = report(config, results, command, time.perf_counter() - started, (load_start, os.getloadavg()[0]))
    print(text)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w", encoding="utf-8") as fh:
        fh.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
