"""One job: recording → split → per fold: select sensors → Optuna study tunes the model → refit → evaluate vs
baselines.

What is true for every honest split (``Split.protocol == "honest"``): everything that produces a fold's held-out
prediction sees only that fold's training rows. Per fold (nested), the selector is fitted on the training part,
the study tunes on an inner validation fold inside it (``splits.inner_fold``; a selector that declares a search
space is tuned jointly with the model: each trial selects on the inner training rows), models scale inside their own
``fit``, and the best parameters are refitted on the training part. So the held-out part is touched once, by the
refit model and the persistence and MLR baselines beside it. A model with history (``history_length != 0``)
gets, for each contiguous block of rows it predicts, the input rows just before the block as ``history``
(held-out: every earlier input row, as a controller would have them; inner validation: the training rows just
before it); measured targets never reach a prediction except through ``lag1:`` columns of models that declare
``uses_target_history`` (the persistence reference). A paper protocol (``shuffled``) runs the same code and is
labelled ``"paper"``: its rows leak by construction.

One Optuna study per fold: a single-fold split keeps the plain study name, fold k of n adds ``-fold<k>of<n>``;
``n_trials`` is the budget of each fold's study. Failed trials are recorded as FAIL and the study goes on; a
re-run with the same storage resumes and keeps completed trials (only the missing number of trials is run).
``n_trials=0`` runs no study: the model is refitted on its defaults (``model_params``), untuned.
"""

from __future__ import annotations

import contextlib
import difflib
import hashlib
import json
import warnings
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import optuna
import pandas as pd

from thermodrift.core import efficiency, registry, resume, schema, search_space, splits, trial_faults, training
from thermodrift.core.errors import InputError
from thermodrift.core.metrics import evaluate
from thermodrift.core.components import LAG_PREFIX, RUN_STARTS
from thermodrift.core.recording import INPUT_ROLES, TARGET_ROLES  # what a model reads (°C, W/m², W) and predicts

SELECTOR_PREFIX = "selector."  # Optuna parameter names of the selector's search space
FINISHED = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED, optuna.trial.TrialState.FAIL)


@dataclass
class JobSpec:
    """What one job runs: component names with their constructor params, and the study settings."""

    dataset: str
    model: str
    selector: str = "all"
    optimizer: str = "tpe"
    split: str = "condition_holdout"
    dataset_params: dict = field(default_factory=dict)
    model_params: dict = field(default_factory=dict)
    model_search_space: dict | None = None  # None: the model's own default
    selector_search_space: dict | None = None  # None: the selector's own default; tuned jointly with the model
    selector_params: dict = field(default_factory=dict)
    optimizer_params: dict = field(default_factory=dict)
    split_params: dict = field(default_factory=dict)
    targets: list[str] | None = None  # displacement or temperature channels (None: every displacement)
    input_roles: tuple[str, ...] = INPUT_ROLES
    baselines: tuple[str, ...] = ("persistence", "mlr")
    seed: int = 0
    n_trials: int = 20  # per fold's study; 0: no study, the model runs untuned on model_params
    timeout_s: float | None = None
    pruner: str = "median"  # stops unpromising trials from the trainer's reports; see PRUNERS
    storage: str | None = "sqlite:///optuna.db"
    study_name: str | None = None
    progress: bool = True
    threads: int = 1  # torch CPU threads; 1 is fastest for small thermal networks

    def model_space(self) -> dict:
        """The model's search space: ``model_search_space``, else the registered model's own."""
        return (self.model_search_space if self.model_search_space is not None
                else registry.get("model", self.model).factory.search_space())

    def budget(self) -> int:
        """Trials each fold's study runs: ``n_trials``, or one when the model has nothing to tune."""
        return self.n_trials if self.model_space() else 1

    def default_study_name(self) -> str:
        """Stable name from everything that defines the search except the budget, so re-runs resume."""
        key = {k: v for k, v in self.__dict__.items() if k not in (
            "n_trials", "timeout_s", "pruner", "storage", "study_name", "progress", "baselines", "threads")}
        digest = hashlib.sha1(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()[:10]
        return f"{self.dataset}-{self.selector}-{self.model}-{self.optimizer}-{self.split}-s{self.seed}-{digest}"


#: ``optuna.pruner`` names: the pruner that stops a trial whose trainer reports (inner validation RMSE per
#: epoch cycle, µm) fall behind. ``median`` is Optuna's default; ``none`` runs every trial to its end.
PRUNERS: dict[str, Callable[[], optuna.pruners.BasePruner]] = {
    "median": optuna.pruners.MedianPruner,
    "hyperband": optuna.pruners.HyperbandPruner,
    "successive_halving": optuna.pruners.SuccessiveHalvingPruner,
    "none": optuna.pruners.NopPruner,
}


def make_pruner(name: str) -> optuna.pruners.BasePruner:
    """The Optuna pruner called ``name`` (a key of :data:`PRUNERS`)."""
    if name not in PRUNERS:
        hint = difflib.get_close_matches(str(name), PRUNERS, n=1)
        raise InputError(f"optuna.pruner={name!r} is not a pruner",
                         hint=(f"did you mean {hint[0]!r}? " if hint else "") + f"choose from {sorted(PRUNERS)}")
    return PRUNERS[name]()


@dataclass
class FoldResult:
    """One fold: what was selected and tuned on its training part, and the held-out predictions and metrics (µm)
    of the refit model and the baselines. ``study`` is None when ``n_trials=0`` (untuned)."""

    name: str
    time_s: np.ndarray
    y_true: pd.DataFrame
    predictions: dict[str, np.ndarray]  # "model" and each baseline name -> (n, k) µm
    metrics: dict[str, dict[str, dict[str, float]]]  # same keys -> channel -> metric -> value
    selected: list[str] = field(default_factory=list)
    best_params: dict[str, Any] = field(default_factory=dict)
    valid_rmse: float = float("nan")  # the inner validation RMSE (µm) of best_params
    study: optuna.Study | None = None
    trials_before: int = 0  # finished trials found in the storage before this run
    model: Any = None  # refit on this fold's training part
    selector: Any = None  # fitted on this fold's training part; its ``report_`` (if any) is logged
    efficiency: dict[str, float] = field(default_factory=dict)  # the refit model's costs (core/efficiency.py)
    train_rows: np.ndarray | None = None  # positions of the rows ``model`` was refitted on (its export's limits)


@dataclass
class JobResult:
    """Every fold's result; ``study``, ``selected``, ``best_params`` and ``model`` are the last fold's (for
    forward chaining, the one trained on the most data)."""

    spec: JobSpec
    folds: list[FoldResult]
    protocol: str
    notes: list[str] = field(default_factory=list)
    recording: Any = None  # the recording the job ran on

    @property
    def study(self) -> optuna.Study | None:
        return self.folds[-1].study

    @property
    def selected(self) -> list[str]:
        return self.folds[-1].selected

    @property
    def best_params(self) -> dict[str, Any]:
        return self.folds[-1].best_params

    @property
    def model(self) -> Any:
        return self.folds[-1].model

    @property
    def valid_rmse(self) -> float:
        """Mean over folds of the inner validation RMSE (µm): what a sweep over jobs may minimise."""
        return float(np.mean([f.valid_rmse for f in self.folds]))

    def summary_metrics(self, who: str = "model", channel: str = "mean") -> dict[str, float]:
        """Mean over folds of the metrics of ``who`` ("model" or a baseline name) on ``channel`` (a target, or
        "mean": the mean over targets)."""
        names = self.folds[0].metrics[who][channel].keys()
        return {m: float(np.mean([f.metrics[who][channel][m] for f in self.folds])) for m in names}

    @property
    def targets(self) -> list[str]:
        return list(self.folds[0].y_true.columns)

    @property
    def unit(self) -> str:
        """The unit of the errors: µm for displacement targets, K for temperature targets."""
        return target_unit(self.recording, self.targets)

    def same_as(self, atol_um: float = 1e-3) -> str | None:
        """The baseline whose held-out predictions equal the model's on every row of every fold to ``atol_um``
        (default 0.001 µm, the precision the metrics are printed with), if any."""
        for base in self.spec.baselines:
            if all(np.allclose(f.predictions["model"], f.predictions[base], rtol=0, atol=atol_um)
                   for f in self.folds):
                return base
        return None


class Job:
    """Runs a :class:`JobSpec`. ``callbacks`` are Optuna callbacks (e.g. the MLflow trial logger); ``say`` gets
    one-line messages for the person running it (a resumed study's counts)."""

    def __init__(self, spec: JobSpec, callbacks: list[Callable] | None = None,
                 say: Callable[[str], None] | None = None):
        self.spec = spec
        self.callbacks = list(callbacks or [])
        self.say = say or (lambda line: None)
        self.unit = "µm"  # of the errors, once :meth:`run` knows the targets: µm (displacement) or K (temperature)

    def run(self, recording=None) -> JobResult:
        """Run the job on ``recording`` (default: the spec's dataset from the registry)."""
        spec = self.spec
        if spec.n_trials < 0:
            raise InputError(f"n_trials must be 0 (untuned) or more, got {spec.n_trials}")
        make_pruner(spec.pruner)  # a misspelt pruner is answered before any work
        if recording is None:
            recording = registry.create("dataset", spec.dataset, **spec.dataset_params)
        targets = targets_of(recording, self.spec.targets)
        self.unit = target_unit(recording, targets)
        lacking = [r for r in getattr(registry.get("model", spec.model).factory, "requires_roles", ())
                   if not recording.columns(r)]
        if lacking:
            raise InputError(f"{recording.source}: model {spec.model} needs a channel of role {lacking[0]}, and the "
                             "recording has none", hint="choose another model, or give that channel in the manifest")
        split = splits.make_split(spec.split, seed=spec.seed, **spec.split_params)
        folds = split.folds(recording)
        features = input_columns(recording, spec.input_roles, targets)
        if not features:
            raise InputError(f"{recording.source}: no input channel with roles {list(spec.input_roles)}")
        space = spec.model_space()
        search_space.distributions(space)  # a malformed space fails here, before any trial
        optuna.logging.set_verbosity(optuna.logging.WARNING)  # the progress bar shows the trials
        training.set_num_threads(spec.threads)
        base = spec.study_name or spec.default_study_name()
        results = []
        for k, fold in enumerate(folds, 1):
            name = base if len(folds) == 1 else f"{base}-fold{k}of{len(folds)}"
            results.append(self._fold(recording, fold, features, targets, space, name))
        return JobResult(spec, results, split.protocol, notes=list(getattr(recording, "notes", [])),
                         recording=recording)

    def _fold(self, recording, fold: splits.Fold, features: list[str], targets: list[str], space: dict,
              study_name: str) -> FoldResult:
        """Select, tune, refit and evaluate on one fold; only ``fold.train`` rows reach selection and tuning."""
        return _FoldRun(self, recording, fold, features, targets, space, study_name).run()

    @staticmethod
    def storage(url: str) -> optuna.storages.RDBStorage:
        """The Optuna storage at ``url`` (creating its schema). Heartbeats let a later run mark the trials of a
        killed run as failed instead of running forever."""
        def create() -> optuna.storages.RDBStorage:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                return optuna.storages.RDBStorage(url, heartbeat_interval=30, grace_period=90)
        return schema.retrying(create, url)  # workers that start together on a new database

    def _study(self, name: str) -> optuna.Study:
        spec = self.spec
        return open_study(name, spec.storage, spec.optimizer, spec.seed, spec.n_trials, spec.optimizer_params,
                          make_pruner(spec.pruner))


def open_study(name: str, storage: str | None, optimizer: str, seed: int, n_trials: int,
               optimizer_params: dict | None = None, pruner: optuna.pruners.BasePruner | None = None) -> optuna.Study:
    """The Optuna study ``name`` (created, or loaded to resume) in ``storage`` (None: in memory), sampled by the
    registered optimizer ``optimizer`` seeded with ``seed``."""
    sampler = registry.create_sampler(optimizer, seed=seed, n_trials=n_trials, **(optimizer_params or {}))
    rdb = Job.storage(storage) if storage else None
    return schema.retrying(lambda: optuna.create_study(study_name=name, storage=rdb, sampler=sampler, pruner=pruner,
                                                       direction="minimize", load_if_exists=True), storage)


def seeded_model(name: str, params: dict, seed: int):
    """The registered model ``name`` on ``params``, with ``seed`` where it takes one and ``params`` do not set it."""
    return registry.create("model", name, **registry.with_seed(registry.get("model", name).factory, params, seed))


def refit(models: list[tuple[str, str, dict]], inputs: Callable[[str, str], pd.DataFrame], y: pd.DataFrame,
          rows: np.ndarray, seed: int) -> tuple[dict[str, Any], dict[str, float]]:
    """Each ``(who, model name, params)`` of ``models`` fitted on ``rows`` of its input frame ``inputs(who, name)``
    and of ``y`` (µm); and the costs of ``who == "model"`` (core/efficiency.py), timed on those rows."""
    fitted: dict[str, Any] = {}
    cost: dict[str, float] = {}
    for who, name, params in models:
        frame = inputs(who, name)
        started = time.perf_counter()
        fitted[who] = seeded_model(name, params, seed).fit(frame.iloc[rows], y.iloc[rows])
        if who == "model":
            cost = efficiency.measure(fitted[who], frame, rows, time.perf_counter() - started)
    return fitted, cost


def score(fitted: dict[str, Any], names: dict[str, str], inputs: Callable[[str, str], pd.DataFrame],
          y: pd.DataFrame, rows: np.ndarray) -> tuple[dict[str, np.ndarray], dict]:
    """Held-out predictions (µm) on ``rows`` of every fitted model (``names``: who -> model name, for its inputs
    ``inputs(who, name)``) and their metrics; a model with history gets every earlier input row."""
    preds = {who: predict_rows(m, inputs(who, names[who]), rows) for who, m in fitted.items()}
    y_test = y.iloc[rows]
    return preds, {who: evaluate(y_test, p) for who, p in preds.items()}


@dataclass
class _Tuned:
    """What tuning settled on a fold: the model's parameters, their inner validation RMSE (µm), the selector's
    tuned parameters (None: not tuned), the study (None: untuned) and its finished trials before this run."""

    params: dict[str, Any]
    valid_rmse: float
    selector_params: dict[str, Any] | None = None
    study: optuna.Study | None = None
    trials_before: int = 0


class _FoldRun:
    """One fold of a :class:`Job` in four named steps: :meth:`select` sensors, :meth:`tune` the model on the
    inner validation fold, :meth:`refit` the best parameters and the baselines on the training part, and
    :meth:`evaluate` them once on the held-out part. Only ``fold.train`` rows reach the first three."""

    def __init__(self, job: Job, recording, fold: splits.Fold, features: list[str], targets: list[str],
                 space: dict, study_name: str):
        self.job, self.spec, self.recording, self.fold = job, job.spec, recording, fold
        self.targets, self.space, self.study_name = targets, space, study_name
        self.X, self.y = recording.data[features], recording.data[targets]
        self.selector_factory = registry.get("selector", self.spec.selector).factory
        sel_space = (self.spec.selector_search_space if self.spec.selector_search_space is not None
                     else self.selector_factory.search_space())
        self.selector_space = ({f"{SELECTOR_PREFIX}{k}": v for k, v in (sel_space or {}).items()}
                               if self.spec.n_trials else {})
        search_space.distributions(self.selector_space)
        inner = splits.inner_fold(recording.select(fold.train))
        self.inner_train, self.inner_val = fold.train[inner.train], fold.train[inner.test]
        self._frames: dict[tuple, pd.DataFrame] = {}

    def run(self) -> FoldResult:
        selector = self.select({}, self.fold.train)
        tuned = self.tune(selector)
        if tuned.selector_params is not None:  # the best trial's selector parameters, on the whole training part
            selector = self.select(tuned.selector_params, self.fold.train)
        fitted, cost = self.refit(tuned.params, selector.selected_)
        preds, metrics = self.evaluate(fitted, selector.selected_)
        fold = self.fold
        return FoldResult(fold.name, self.recording.time_s[fold.test], self.y.iloc[fold.test], preds, metrics,
                          selected=list(selector.selected_), best_params=tuned.params, valid_rmse=tuned.valid_rmse,
                          study=tuned.study, trials_before=tuned.trials_before, model=fitted["model"],
                          selector=selector, efficiency=cost, train_rows=fold.train)

    # ------------------------------------------------------------------------------------------------ the steps
    def select(self, params: dict, rows: np.ndarray):
        """The selector fitted on ``rows`` with the spec's parameters and ``params`` on top."""
        spec = self.spec
        sel = registry.create("selector", spec.selector,
                              **registry.with_seed(self.selector_factory, {**spec.selector_params, **params}, spec.seed))
        return sel.fit(self.X.iloc[rows], self.y.iloc[rows])

    def tune(self, selector) -> _Tuned:
        """The model's best parameters by inner validation RMSE (µm): an Optuna study of ``n_trials`` (resumed
        from the storage), or with ``n_trials=0`` the spec's ``model_params``, untuned."""
        spec = self.spec
        if spec.n_trials == 0:
            params = dict(spec.model_params)
            return _Tuned(params, self.validate(params, selector.selected_))
        study = self.job._study(self.study_name)
        resume.fail_dead_trials(study)  # a killed run's trials; they do not count against the budget
        done = sum(t.state in FINISHED and not resume.was_killed(t) for t in study.trials)
        budget = spec.budget()
        if done:
            complete = sum(t.state == optuna.trial.TrialState.COMPLETE for t in study.trials)
            self.job.say(f"study {self.study_name} resumed: {complete} of {max(budget, done)} trials complete"
                         f"{f' ({done - complete} failed or pruned)' if done > complete else ''}, "
                         f"{max(0, budget - done)} to run")
        if done < budget:  # other workers on the same study count too: the budget is the study's
            study.optimize(trial_faults.reporting(lambda trial: self.objective(trial, selector)),
                           n_trials=budget - done, timeout=spec.timeout_s, catch=(Exception,),
                           callbacks=[*self.job.callbacks, resume.StudyBudget(budget)],
                           show_progress_bar=spec.progress)
        resume.fail_dead_trials(study)  # a worker killed while this one ran
        if not any(t.state == optuna.trial.TrialState.COMPLETE for t in study.trials):
            reasons = {t.user_attrs.get("fail_reason") or t.system_attrs.get("fail_reason") for t in study.trials}
            raise InputError(f"all {len(study.trials)} trials of study {study.study_name!r} failed: "
                             f"{'; '.join(sorted(str(r) for r in reasons if r))[:300]}")
        tuned = study.best_params
        params = _nested({**spec.model_params,
                          **{k: v for k, v in tuned.items() if not k.startswith(SELECTOR_PREFIX)}})
        sel_params = ({k.removeprefix(SELECTOR_PREFIX): v for k, v in tuned.items() if k.startswith(SELECTOR_PREFIX)}
                      if self.selector_space else None)
        return _Tuned(params, float(study.best_value), sel_params, study, done)

    def refit(self, params: dict, selected: list[str]) -> tuple[dict[str, Any], dict[str, float]]:
        """The model on ``params`` and each baseline, fitted on the training part; and the model's costs
        (core/efficiency.py), timed on training rows: the held-out rows are touched once, by :meth:`evaluate`."""
        spec = self.spec
        return refit([("model", spec.model, params)] + [(b, b, {}) for b in spec.baselines],
                     lambda who, name: self.inputs(name, selected), self.y, self.fold.train, spec.seed)

    def evaluate(self, fitted: dict[str, Any], selected: list[str]) -> tuple[dict[str, np.ndarray], dict]:
        """Held-out predictions (µm) of every fitted model ("model" and each baseline) and their metrics."""
        spec = self.spec
        names = {"model": spec.model, **{b: b for b in spec.baselines}}
        return score(fitted, names, lambda who, name: self.inputs(name, selected), self.y, self.fold.test)

    # ------------------------------------------------------------------------------------------------ tuning parts
    def objective(self, trial: optuna.Trial, selector) -> float:
        """One trial: suggest, fit on the inner training rows, and return the inner validation RMSE (µm)."""
        resume.claim(trial)
        chosen = selector.selected_
        if self.selector_space:  # the selector's parameters are tuned jointly: it selects on the inner training rows
            sel_params = {k.removeprefix(SELECTOR_PREFIX): v
                          for k, v in search_space.suggest(trial, self.selector_space).items()}
            chosen = self.select(sel_params, self.inner_train).selected_
            trial.set_user_attr("selected", ",".join(chosen))
        try:
            rmse = self.validate({**self.spec.model_params, **search_space.suggest(trial, self.space)}, chosen, trial)
        except training.DivergedError as exc:
            trial.set_user_attr("diverged", True)
            trial.set_user_attr("fail_reason", str(exc))
            raise
        if not np.isfinite(rmse):
            raise ValueError(f"validation RMSE is {rmse}")
        return rmse

    def validate(self, params: dict, selected: list[str], trial: optuna.Trial | None = None) -> float:
        """Inner validation RMSE (µm) of the model on ``params``, fitted on the inner training rows."""
        model = seeded_model(self.spec.model, params, self.spec.seed)
        frame = self.inputs(self.spec.model, selected)
        with training.reporting(trial) if trial is not None else contextlib.nullcontext():
            model.fit(frame.iloc[self.inner_train], self.y.iloc[self.inner_train])
        pred = predict_rows(model, frame, self.inner_val, allowed=self.fold.train)
        rmse = evaluate(self.y.iloc[self.inner_val], pred)["mean"]["rmse"]
        if trial is not None:
            report = getattr(model, "train_report_", None)  # torch models: epochs, grad-norm statistics
            for key, value in (report.metrics() if report is not None else {}).items():
                trial.set_user_attr(f"train/{key}", value)
        return rmse

    def inputs(self, model_name: str, selected: list[str]) -> pd.DataFrame:
        """The input frame of ``model_name`` on ``selected`` columns for every recording row (built once)."""
        key = (model_name, tuple(selected))
        if key not in self._frames:
            cls = registry.get("model", model_name).factory
            self._frames[key] = model_inputs(self.recording, list(selected), cls, self.targets)
        return self._frames[key]


def targets_of(recording, wanted: list[str] | None) -> list[str]:
    """The channels to model: ``wanted`` (displacement or temperature channels), else every displacement.
    :class:`InputError` (one line) for a name that is not such a channel: an input (ambient, speed, heating, ...)
    is never a target."""
    available = [c for c in recording.data.columns if recording.channels[c].role in TARGET_ROLES]
    if not wanted:
        default = recording.columns("displacement")
        if not default:
            temps = recording.columns("temperature")
            raise InputError(f"{recording.source}: the recording has no displacement channel to model",
                             hint=f"name a temperature target, e.g. targets=['{temps[0]}']" if temps else
                             "give a column role: displacement or temperature in the manifest")
        return default
    wrong = [t for t in wanted if t not in available]
    if wrong:
        name = wrong[0]
        role = recording.channels[name].role if name in recording.channels else None
        what = (f"is a channel of role {role}, an input" if role else "is not a channel of the recording")
        raise InputError(f"{recording.source}: target {name!r} {what}; a target is a displacement or temperature "
                         "channel", hint=f"choose from {available}")
    return list(dict.fromkeys(wanted))


def target_unit(recording, targets: list[str]) -> str:
    """The unit of errors of ``targets``: µm (displacement), K (temperature); µm for a recording without roles."""
    channels = getattr(recording, "channels", None)
    return recording.error_unit(targets) if channels and all(t in channels for t in targets) else "µm"


def input_columns(recording, roles, targets: list[str]) -> list[str]:
    """The recording's channels of ``roles`` in role order, without the ``targets`` (a target is never an input)."""
    return [c for role in roles for c in recording.columns(role) if c not in targets]


def model_inputs(recording, selected: list[str], model_cls, targets: list[str], lag: int = 1) -> pd.DataFrame:
    """The input frame a model of class ``model_cls`` gets, for every row of ``recording``: the ``selected``
    input columns (temperatures °C, heat inputs), the channels of its ``extra_input_roles`` (e.g. speed in rpm),
    and for models that use the target history ``lag1:<target>``, the last measured target (µm or °C): that of
    the previous sample, or ``lag`` samples before at a forecast horizon of ``lag`` samples
    (:mod:`thermodrift.core.horizons`). ``attrs["roles"]`` maps every column to its role. No target is ever an
    input column."""
    leaked = [c for c in selected if c in targets]
    if leaked:
        raise ValueError(f"targets {leaked} are among the selected inputs; a target is never an input")
    X = recording.data[list(selected)]
    extra = [c for role in getattr(model_cls, "extra_input_roles", ()) for c in recording.columns(role)
             if c not in selected and c not in targets]
    parts = [X, recording.data[extra]] if extra else [X]
    if getattr(model_cls, "uses_target_history", False):
        parts.append(recording.data[targets].shift(lag).ffill().bfill().add_prefix(LAG_PREFIX))
    out = pd.concat(parts, axis=1) if len(parts) > 1 else X.copy()
    # Each column's role travels with the frame (and its row slices), so models need not guess from names.
    out.attrs["roles"] = {c: recording.channels[c].role if c in recording.channels else "target_history"
                          for c in out.columns}
    if recording.run_starts_s:  # several runs: models with history start each afresh
        out.attrs[RUN_STARTS] = list(recording.run_starts_s)
    return out


def predict_rows(model, frame: pd.DataFrame, rows: np.ndarray, allowed: np.ndarray | None = None) -> np.ndarray:
    """``model``'s predictions (µm) for ``rows`` (sorted positions into ``frame``, the model's inputs for every row
    of the recording). A model with history predicts with the input rows before ``rows`` as ``history``: every
    earlier row (one prediction over the span from the first to the last of ``rows``: inputs only), or, with
    ``allowed``, per contiguous block of ``rows`` the unbroken run of ``allowed`` rows that ends just before it."""
    if getattr(model, "history_length", 0) == 0:
        return model.predict(frame.iloc[rows])
    if allowed is None:
        first = int(rows[0])
        pred = model.predict(frame.iloc[first:int(rows[-1]) + 1], history=frame.iloc[:first])
        return pred[rows - first]
    ok = np.zeros(len(frame), dtype=bool)
    ok[allowed] = True
    out = []
    for block in np.split(rows, np.flatnonzero(np.diff(rows) != 1) + 1):
        start = int(block[0])
        gaps = np.flatnonzero(~ok[:start])
        begin = int(gaps[-1]) + 1 if len(gaps) else 0
        out.append(model.predict(frame.iloc[block], history=frame.iloc[begin:start]))
    return np.concatenate(out)


def _nested(params: dict[str, Any]) -> dict[str, Any]:
    """Tuned nested names (``trainer__lr_max``) folded into their dict parameter (``trainer``), so the best
    parameters state each value once."""
    out = dict(params)
    for key in [k for k in out if "__" in k]:
        outer, inner = key.split("__", 1)
        if isinstance(out.get(outer), dict):
            out[outer] = {**out[outer], inner: out.pop(key)}
    return out
