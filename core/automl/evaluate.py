"""Scoring one candidate pipeline on the inner folds: fit on each fold's training rows, predict its validation
rows with the training rows before them as history, RMSE per fold and target in the targets' unit (µm for
displacements, K for temperatures: :attr:`Evaluator.unit`), and its costs.

With ``n_jobs`` > 1 the fold fits run in worker processes (forked from this one, so they share the recording,
the registry and its plugins without pickling them); :meth:`Evaluator.evaluate_many` runs the folds of several
candidates at once. Every fit is a pure function of its candidate, fold and seed, so the scores do not depend on
``n_jobs`` (only the measured times do).

A sparse target (a drift measured now and then: measured on fewer than half of the training rows) caps a
candidate's parameters by its measurements: each probe reading is one equation, so a pipeline whose fitted model has
more trainable parameters than the outer training part has measured rows (the rows its refit will learn from) is
underdetermined there, and its inner scores, on folds of a handful of readings, cannot show it; it is left out
(:class:`Underdetermined`, raised after its first fold's fit, :func:`free_parameters`). A densely measured target
is not capped: its rows are a time series sampled far faster than its dynamics, not independent equations, and its
networks are fitted by early stopping on them.
"""

from __future__ import annotations

import multiprocessing
import pickle
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from thermodrift.core import efficiency, registry
from thermodrift.core.automl.folds import aggregate
from thermodrift.core.metrics import evaluate
from thermodrift.core.study import INPUT_ROLES, input_columns, model_inputs, predict_rows, seeded_model, target_unit


SPARSE_SHARE = 0.5  # a target measured on fewer than this share of the training rows is sparse (see above)


class Underdetermined(ValueError):
    """A candidate with more trainable parameters than the measured rows of a sparse target's training part."""


def free_parameters(model) -> int:
    """A fitted model's trainable parameters (:func:`.efficiency.parameter_count`); where it does not
    expose them (0), one per input column its inner model reads plus an offset, the least a regression on them has."""
    count = efficiency.parameter_count(model)
    columns = getattr(model, "inner_columns_", None)
    return count if count or not columns else len(columns) + 1


@dataclass
class Evaluation:
    """A candidate's inner-fold result: RMSE (µm, mean over targets) per fold, per target (mean over folds), the
    aggregated score, the validation predictions per fold (for the ensemble), and costs of the last fold's fit."""

    fold_rmse: list[float]
    target_rmse: dict[str, float]
    score: float
    predictions: list[np.ndarray] = field(repr=False, default_factory=list)
    fit_s: float = 0.0
    costs: dict[str, float] = field(default_factory=dict)


class Evaluator:
    """Fits ``pipeline`` candidates on the inner ``folds`` of ``recording`` (all inside ``outer_train``)."""

    def __init__(self, recording, outer_train: np.ndarray, targets: list[str], folds, seed: int = 0,
                 n_jobs: int = 1):
        self.recording, self.targets, self.folds, self.seed = recording, list(targets), list(folds), seed
        self.n_jobs, self._pool = max(1, int(n_jobs)), None
        self.outer_train = np.asarray(outer_train)
        cls = registry.get("model", "pipeline").factory
        inputs = input_columns(recording, INPUT_ROLES, self.targets)
        self.X = model_inputs(recording, inputs, cls, self.targets)
        self.y = recording.data[self.targets]
        # outer training rows with every target measured: all of them unless the drift is measured now and then
        self.labelled = int(np.isfinite(self.y.iloc[self.outer_train].to_numpy(dtype=float)).all(axis=1).sum())
        self.truth = [self.y.iloc[f.test] for f in self.folds]
        self.unit = target_unit(recording, self.targets)  # of every RMSE here: µm or K
        self.roles = {ch.role for ch in recording.channels.values()}  # what families may require (speed, ...)
        # the parameter cap of a sparse target (module docstring); None: dense, no cap
        self.max_parameters = self.labelled if self.labelled < SPARSE_SHARE * len(self.outer_train) else None

    def pipeline(self, params: dict):
        return seeded_model("pipeline", params, self.seed)

    def evaluate(self, params: dict, measure_costs: bool = True) -> Evaluation:
        """Fit and score ``params`` (a pipeline's parameters) on every fold; exceptions propagate."""
        out = self.evaluate_many([params], measure_costs)[0]
        if isinstance(out, Exception):
            raise out
        return out

    def evaluate_many(self, many: list[dict], measure_costs: bool = True) -> list[Evaluation | Exception]:
        """:meth:`evaluate` of each of ``many``, their folds in parallel over ``n_jobs`` processes; a candidate
        whose fit fails gets the exception of its first failing fold."""
        tasks = [(params, k, measure_costs) for params in many for k in range(len(self.folds))]
        if self.n_jobs == 1 or len(tasks) == 1:
            done: list = []
            for params in many:  # one after another, a candidate stopping at its first failing fold
                for k in range(len(self.folds)):
                    done.append(self._fold(params, k, measure_costs))
                    if isinstance(done[-1], Exception):
                        done += [done[-1]] * (len(self.folds) - 1 - k)
                        break
        else:
            done = list(self._executor().map(_fold_task, tasks))
        n = len(self.folds)
        return [self._combine(done[i * n:(i + 1) * n]) for i in range(len(many))]

    def _fold(self, params: dict, k: int, measure_costs: bool):
        """Fold ``k`` of ``params``: (prediction, RMSE µm, RMSE per target, fit s, costs of the last fold), or
        the exception its fit or prediction raised."""
        fold, truth = self.folds[k], self.truth[k]
        try:
            started = time.perf_counter()
            model = self.pipeline(params).fit(self.X.iloc[fold.train], self.y.iloc[fold.train])
            fit_s = time.perf_counter() - started
            if self.max_parameters is not None and k == 0:
                count = free_parameters(model)
                if count > self.max_parameters:
                    raise Underdetermined(f"{count} parameters, more than the {self.max_parameters} measured rows "
                                          "of the training part")
            pred = predict_rows(model, self.X, fold.test, allowed=self.outer_train)
            if not np.isfinite(pred).all():
                raise ValueError("non-finite predictions on an inner fold")
            metrics = evaluate(truth, pred)
            costs = efficiency.measure(model, self.X, fold.test, fit_s) \
                if measure_costs and k == len(self.folds) - 1 else {}
        except Exception as exc:  # reported per candidate by the search
            return exc
        return pred, float(metrics["mean"]["rmse"]), [float(metrics[t]["rmse"]) for t in self.targets], fit_s, costs

    def _combine(self, folds: list) -> Evaluation | Exception:
        failed = next((f for f in folds if isinstance(f, Exception)), None)
        if failed is not None:
            return failed
        preds, fold_rmse, per_target, fit_times, costs = (list(x) for x in zip(*folds))
        fit_s = float(sum(fit_times))
        cost = dict(costs[-1])
        if cost:
            cost["train_s"] = fit_s / len(self.folds)
        target_rmse = dict(zip(self.targets, np.mean(per_target, axis=0).tolist()))
        return Evaluation(fold_rmse, target_rmse, aggregate(fold_rmse), preds, fit_s, cost)

    def _executor(self) -> ProcessPoolExecutor:
        """The worker processes, forked on first use with this evaluator (see the module docstring)."""
        if self._pool is None:
            import torch

            global _WORKER
            _WORKER = self
            self._pool = ProcessPoolExecutor(self.n_jobs, mp_context=multiprocessing.get_context("fork"),
                                             initializer=_init_worker, initargs=(torch.get_num_threads(),))
        return self._pool

    def close(self) -> None:
        """Stop the worker processes (if any)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def fold_rmse(self, pred: np.ndarray, k: int) -> float:
        """RMSE (µm, mean over targets) of ``pred`` on inner fold ``k``'s validation rows."""
        return float(evaluate(self.truth[k], pred)["mean"]["rmse"])

    def score_predictions(self, preds: list[np.ndarray]) -> tuple[list[float], float]:
        """Per-fold RMSE (µm, mean over targets) and the aggregated score of given fold predictions."""
        rmse = [self.fold_rmse(p, k) for k, p in enumerate(preds)]
        return rmse, aggregate(rmse)


_WORKER: Evaluator | None = None  # the evaluator a forked worker process inherited


def _init_worker(threads: int) -> None:
    import torch

    torch.set_num_threads(threads)  # the parent's setting: a fit's arithmetic does not depend on the process


def _fold_task(task):
    params, k, measure_costs = task
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = _WORKER._fold(params, k, measure_costs)
    if isinstance(out, Exception):
        try:
            pickle.loads(pickle.dumps(out))
        except Exception:  # an exception that does not travel between processes: its type name and message do
            out = RuntimeError(f"{type(out).__name__}: {out}")
    return out
