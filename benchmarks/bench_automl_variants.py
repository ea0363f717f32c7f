"""Final-choice variants of ``thermodrift automl`` replayed offline, each written down before its replay (see
``docs/automl_benchmark.md``, "Six more rules and two larger portfolios"): the search's rule with one
of its pieces swapped, on the inner-fold and held-out predictions that
``bench_automl.py --inner-table --inner-tpe`` keeps per task.

    python benchmarks/bench_automl_variants.py --tasks TASK ...   # default: every task with kept predictions
    python benchmarks/bench_automl_variants.py --portfolio          # also the two larger portfolios

Variants (the rest of the rule as in :mod:`thermodrift.core.automl.search`):

- ``size-weighted mean``: the inner score is the mean of the fold RMSEs weighted by each fold's training rows,
  instead of (mean + worst) / 2;
- ``(mean + last) / 2``: the worst fold replaced by the last (the most training rows);
- ``mean``: the plain mean of the fold RMSEs;
- ``log-difference SE``: the one-standard-error test (the one-SE set and the TPE candidates' admission) on
  per-fold differences of log RMSE instead of µm;
- ``log SE + geometric mean``: the same, and the inner score the geometric mean of the fold RMSEs;
- ``a-priori only``: TPE candidates never enter the final choice.

With ``--portfolio``, also two larger portfolios (their extra candidates scored on the inner folds and held out,
kept in ``<cache>/variants/``; 0.5–3 minutes per task):

- ``penalty path without a feature stage``: every family that takes no feature stage and has a ridge penalty
  ``alpha`` (``lptn_hybrid``, ``mnr``) also along :data:`~thermodrift.core.automl.space.ALPHA_PATH` on the raw
  inputs, as the feature-taking families already are;
- ``medium families' integer ends``: every medium-cost family (never tuned by TPE: ``lptn``, ``lptn_hybrid``) also
  at each end of each integer parameter of its space (``hidden_nodes`` 0 and 4), one at a time.

Prints the held-out RMSE (µm) per task and the geometric mean of each variant's over the search's rule's per task
group. A swap patches the library function for the replay only (``unittest.mock``): the search itself is not run.
"""

from __future__ import annotations

import argparse
import contextlib
import pickle
import sys
import warnings
from pathlib import Path
from unittest import mock

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_automl as bench  # noqa: E402 - the benchmark next to this script

from thermodrift.core import registry  # noqa: E402
from thermodrift.core.automl import folds, search, space  # noqa: E402


def _on_finite(f):
    """An inner score from ``f`` of the fold RMSEs, infinite when a fold is not finite (as :func:`folds.aggregate`)."""
    def score(r):
        r = np.asarray(r, dtype=float)
        return float(f(r)) if len(r) and np.isfinite(r).all() else float("inf")
    return score


def variants(sizes: list[int]) -> dict[str, dict]:
    """Each variant's patches (target → replacement) for a task whose inner folds train on ``sizes`` rows."""
    size_weighted = _on_finite(lambda r: np.average(r, weights=sizes[-len(r):]))
    mean_last = _on_finite(lambda r: 0.5 * (r.mean() + r[-1]))
    mean = _on_finite(np.mean)
    geometric = _on_finite(lambda r: np.exp(np.mean(np.log(np.maximum(r, 1e-12)))))

    earns = search.earns_its_place

    def earns_log(tuned, reference):
        t, ref = np.asarray(tuned, dtype=float), np.asarray(reference, dtype=float)
        if len(t) < 2 or not (np.isfinite(t).all() and np.isfinite(ref).all() and (t > 0).all() and (ref > 0).all()):
            return earns(tuned, reference)
        return earns(np.log(t), np.log(ref))

    chosen = search.eligible

    def prior_only(ok, prior):
        keep, ref = chosen(ok, prior)
        return [e for e in keep if e.phase != "tpe"], ref

    score = ("thermodrift.core.automl.folds.aggregate", "thermodrift.core.automl.search.aggregate")
    return {"search's rule": {},
            "size-weighted mean": {p: size_weighted for p in score},
            "(mean + last) / 2": {p: mean_last for p in score},
            "mean": {p: mean for p in score},
            "log-difference SE": {"thermodrift.core.automl.search.earns_its_place": earns_log},
            "log SE + geometric mean": {"thermodrift.core.automl.search.earns_its_place": earns_log,
                                        **{p: geometric for p in score}},
            "a-priori only": {"thermodrift.core.automl.search.eligible": prior_only}}


def fold_sizes(name: str, args) -> list[int]:
    """Training rows of each inner fold of ``name`` (as the search forms them)."""
    return [len(f.train) for f in bench.task_folds(name, args)[3]]


def replay(saved: dict, sizes: list[int]) -> dict[str, float]:
    """Held-out RMSE (µm) of the search's final choice under each variant on one task's kept predictions
    ``saved`` (``bench_automl.py --inner-table`` form), its inner folds training on ``sizes`` rows."""
    out = {}
    for label, patches in variants(sizes).items():
        with _patched(patches):  # the inner score as the variant computes it
            task = {**saved, "candidates": [{**c, "score": folds.aggregate(c["fold_rmse"])}
                                            for c in saved["candidates"]]}
            out[label] = bench.final_rules(task)["one-SE inverse-MSE weights"][0]
    return out


def portfolio_variants() -> dict[str, list]:
    """The extra a-priori candidates of each larger portfolio (see the module docstring)."""
    def base(f, model_params):
        return space.Candidate({"model": f.name, "model_params": model_params, "selector": "all",
                                "selector_params": {}, "features": None}, origin="portfolio")

    def default(f, name):
        return registry.get("model", f.name).factory().get_params().get(name)

    fams = [f for f in space.families() if not f.network]
    penalty = [base(f, mp) for f in fams if not f.takes_features and f.space.get("alpha", {}).get("type") == "float"
               for mp, _ in space.penalty_path(f) if mp["alpha"] != default(f, "alpha")]
    ends = [base(f, {k: v}) for f in fams if f.cost == "medium" for k, spec in f.space.items()
            if spec.get("type") == "int" for v in (spec["low"], spec["high"]) if v != default(f, k)]
    return {"penalty path without a feature stage": penalty, "medium families' integer ends": ends}


def extra_candidates(name: str, args) -> dict[str, list[dict]]:
    """Each larger portfolio's extra candidates scored on task ``name`` (kept in ``<cache>/variants/``)."""
    path = args.cache / "variants" / f"{name}-extra-s{args.seed}.pkl"
    if path.exists():
        with open(path, "rb") as fh:
            return pickle.load(fh)
    recording, fold, targets, _, ev = bench.inner_setup(name, args)
    out = {label: [bench.score_candidate(c, "portfolio", recording, fold, targets, ev) for c in cands]
           for label, cands in portfolio_variants().items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        pickle.dump(out, fh)
    return out


@contextlib.contextmanager
def _patched(patches: dict):
    """Several :func:`unittest.mock.patch` at once (target → replacement)."""
    with contextlib.ExitStack() as stack:
        for target, new in patches.items():
            stack.enter_context(mock.patch(target, new))
        yield


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tasks", nargs="*", default=None)
    parser.add_argument("--data", default="../shared/data/fl_thermal/data.xlsx", help="the FL_THERMAL workbook")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cache", type=Path, default=Path(".bench_cache/automl"))
    parser.add_argument("--portfolio", action="store_true", help="also the two larger portfolios (slower)")
    args = parser.parse_args()
    names = [n for n in (args.tasks or bench.TASKS) if (args.cache / f"{n}-inner-s{args.seed}.pkl").exists()]
    if not names:
        sys.exit("no kept inner predictions: run bench_automl.py --inner-table --inner-tpe first")
    warnings.simplefilter("ignore")
    rows = {}
    for n in names:
        with open(args.cache / f"{n}-inner-s{args.seed}.pkl", "rb") as fh:
            saved = pickle.load(fh)
        rows[n] = replay(saved, fold_sizes(n, args))
        if args.portfolio:
            for label, extra in extra_candidates(n, args).items():
                rows[n][label] = bench.final_rules({**saved, "candidates": saved["candidates"] + extra})[
                    "one-SE inverse-MSE weights"][0]
    labels = list(next(iter(rows.values())))
    print("| task | " + " | ".join(labels) + " |")
    print("|---|" + "---:|" * len(labels))
    for n, r in rows.items():
        print(f"| {n} | " + " | ".join(f"{r[v]:.3f}" for v in labels) + " |")
    machines = {n for n in names if "generator" in bench.TASKS[n]}  # every independent machine, however grouped
    groups = {"the issue's tasks": [n for n in names if n not in machines],
              "independent machines": [n for n in names if n in machines]}
    for g, members in groups.items():
        if members:
            print(f"| geometric mean / the search's rule, {g} ({len(members)}) | " + " | ".join(
                f"{np.exp(np.mean([np.log(rows[n][v] / rows[n][labels[0]]) for n in members])):.3f}"
                for v in labels) + " |")


if __name__ == "__main__":
    main()
