"""One automl job: recording → outer split → inner forward-chaining folds inside the training part → search →
the chosen pipeline (or ensemble) refitted on the whole training part → scored once on the held-out part beside
the persistence and MLR baselines, as a :class:`thermodrift.core.study.JobResult` like every job's.

Only the outer training rows reach the search: the held-out rows are touched once, by the refit model's and the
baselines' predictions (with every earlier input row as history, as a controller would have them).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
import warnings
from dataclasses import dataclass

import optuna
import torch

from thermodrift.core import registry, splits
from thermodrift.core.automl import extrapolation, folds as inner, leaderboard, space
from thermodrift.core.automl.evaluate import Evaluator
from thermodrift.core.automl.search import Search, SearchResult, Settings
from thermodrift.core.errors import InputError
from thermodrift.core.study import (FoldResult, JobResult, JobSpec, input_columns, model_inputs, open_study, refit,
                                   score, targets_of)

# The search's sampler, through the registry like every study's: TPE over each family's branch on its own.
SAMPLER, SAMPLER_PARAMS = "tpe", {"n_startup_trials": 8, "multivariate": True, "group": True}


@dataclass
class AutoMLResult:
    """The outer result (``job``: model "pipeline" or "ensemble" with the chosen parameters), the search, its
    leaderboard, and the drivers in which the held-out part leaves the training range (:mod:`.extrapolation`)."""

    job: JobResult
    search: SearchResult
    leaderboard: object  # pandas DataFrame
    study_name: str
    wall_s: float
    extrapolation: list = dataclasses.field(default_factory=list)  # extrapolation.Excursion, farthest first

    def describe(self) -> str:
        """The chosen pipeline (or the ensemble's weighted members) in words."""
        ens = self.search.ensemble
        if ens is None:
            return space.describe(self.search.best.candidate.params)
        return " + ".join(f"{w:.2f} × [{space.describe(m)}]" for w, m in zip(ens["weights"], ens["members"]))

    def extrapolates(self) -> str:
        """One line naming the drivers in which the held-out part extrapolates and how far (empty: none)."""
        what = extrapolation.held_out_part(self.job.folds[0].name)
        return extrapolation.summary(self.extrapolation, what) if self.extrapolation else ""


def study_name(spec: JobSpec, settings: Settings) -> str:
    """Stable name from what defines the search except the budget, so a re-run resumes (a larger budget goes on)."""
    key = {k: v for k, v in dataclasses.asdict(spec).items()
           if k in ("dataset", "dataset_params", "split", "split_params", "targets", "input_roles", "seed")}
    key["settings"] = {k: v for k, v in dataclasses.asdict(settings).items()
                       if k not in ("budget_fits", "timeout_s", "n_jobs")}
    digest = hashlib.sha1(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()[:10]
    return f"automl-{spec.dataset}-{spec.split}-s{spec.seed}-{digest}"


def run(spec: JobSpec, settings: Settings, say=lambda line: None, recording=None) -> AutoMLResult:
    """Search, refit and evaluate (see the module docstring). ``spec`` gives dataset, split, targets, seed,
    storage and progress; its model, selector and optimizer are not used (the search chooses)."""
    started = time.perf_counter()
    if settings.budget_fits < 1:
        raise InputError(f"automl.budget_fits must be 1 or more, got {settings.budget_fits}")
    if settings.timeout_s is not None and settings.timeout_s <= 0:
        raise InputError(f"automl.timeout_s must be positive or null, got {settings.timeout_s}")
    if recording is None:
        recording = registry.create("dataset", spec.dataset, **spec.dataset_params)
    targets = targets_of(recording, spec.targets)
    outer = splits.make_split(spec.split, seed=spec.seed, **spec.split_params).folds(recording)
    if len(outer) != 1:
        raise InputError(f"automl takes a split with one held-out part; split {spec.split!r} gives {len(outer)}",
                         hint="use split=condition_holdout or split=time_window")
    fold = outer[0]
    roles = {ch.role for ch in recording.channels.values()}
    missing = space.left_out(roles, only=settings.families)
    if missing:  # before anything is fitted: the families that cannot run here, and why
        say(space.left_out_line(missing, recording.source))
    if not space.families(only=settings.families, roles=roles):
        raise InputError(f"{recording.source}: no automl family can run on this recording",
                         hint=space.left_out_line(missing, "it").removeprefix("automl: "))
    torch.set_num_threads(spec.threads)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    beyond = extrapolation.check(recording, fold.train, fold.test, targets)
    if beyond:  # said before the search: what its inner folds cannot vouch for unless they extrapolated too
        say(f"thermodrift: warning: {extrapolation.summary(beyond, extrapolation.held_out_part(fold.name))}")
    folds = inner.inner_folds(recording, fold.train, settings.max_folds)
    ev = Evaluator(recording, fold.train, targets, folds, spec.seed, n_jobs=settings.jobs())
    name = spec.study_name or study_name(spec, settings)
    with warnings.catch_warnings():  # TPE's `group` is experimental in Optuna
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        study = open_study(name, spec.storage, SAMPLER, spec.seed, settings.budget_fits, SAMPLER_PARAMS)
    done = sum(t.state.is_finished() for t in study.trials)
    if done:
        say(f"automl study {name} resumed: {done} candidates found")
    result = Search(ev, study, settings, say, spec.progress).run()
    model_name, params = result.chosen()
    job = refit_and_evaluate(spec, recording, fold, targets, model_name, params,
                             result.ensemble["score"] if result.ensemble else result.best.score)
    board = extrapolation.mark(leaderboard.table(result.entries, folds, targets, result.ensemble), recording, folds,
                               targets, registry, beyond)
    return AutoMLResult(job, result, board, name, time.perf_counter() - started, beyond)


def refit_and_evaluate(spec: JobSpec, recording, fold: splits.Fold, targets: list[str], model_name: str,
                       params: dict, inner_score: float) -> JobResult:
    """The chosen model refitted on ``fold.train`` and scored on ``fold.test`` beside ``spec.baselines`` (on every
    input temperature), as the :class:`JobResult` of a job with ``model=model_name``."""
    columns = input_columns(recording, spec.input_roles, targets)
    frames = {}

    def inputs(who: str, name: str):
        if name not in frames:
            frames[name] = model_inputs(recording, columns, registry.get("model", name).factory, targets)
        return frames[name]

    y_all = recording.data[targets]
    models = [("model", model_name, params)] + [(b, b, {}) for b in spec.baselines]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fitted, cost = refit(models, inputs, y_all, fold.train, spec.seed)
    preds, metrics = score(fitted, {who: name for who, name, _ in models}, inputs, y_all, fold.test)
    model = fitted["model"]
    result = FoldResult(fold.name, recording.time_s[fold.test], y_all.iloc[fold.test], preds, metrics,
                        selected=_selected(model),
                        best_params=params, valid_rmse=float(inner_score), model=model, efficiency=cost,
                        train_rows=fold.train)
    job_spec = dataclasses.replace(spec, model=model_name, model_params=params, selector="all", n_trials=0)
    return JobResult(job_spec, [result], splits.make_split(spec.split, seed=spec.seed, **spec.split_params).protocol,
                     notes=list(getattr(recording, "notes", [])), recording=recording)


def _selected(model) -> list[str]:
    members = getattr(model, "members_", None)
    if members is not None:
        return sorted({c for m in members for c in getattr(m, "selected_", [])})
    return list(getattr(model, "selected_", []))

