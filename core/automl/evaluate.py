"""Scoring one candidate pipeline on the inner folds: fit on each fold's training rows, predict its validation
rows with the training rows before them as history, RMSE per fold and target in the targets' unit (µm for
displacements, K for temperatures: :attr:`Evaluator.unit`), and its costs."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from thermodrift.core import efficiency, registry
from thermodrift.core.automl.folds import aggregate
from thermodrift.core.metrics import evaluate
from thermodrift.core.study import INPUT_ROLES, input_columns, model_inputs, predict_rows, seeded_model, target_unit


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

    def __init__(self, recording, outer_train: np.ndarray, targets: list[str], folds, seed: int = 0):
        self.recording, self.targets, self.folds, self.seed = recording, list(targets), list(folds), seed
        self.outer_train = np.asarray(outer_train)
        cls = registry.get("model", "pipeline").factory
        inputs = input_columns(recording, INPUT_ROLES, self.targets)
        self.X = model_inputs(recording, inputs, cls, self.targets)
        self.y = recording.data[self.targets]
        self.truth = [self.y.iloc[f.test] for f in self.folds]
        self.unit = target_unit(recording, self.targets)  # of every RMSE here: µm or K
        self.roles = {ch.role for ch in recording.channels.values()}  # what families may require (speed, ...)

    def pipeline(self, params: dict):
        return seeded_model("pipeline", params, self.seed)

    def evaluate(self, params: dict, measure_costs: bool = True) -> Evaluation:
        """Fit and score ``params`` (a pipeline's parameters) on every fold; exceptions propagate."""
        preds, fold_rmse, per_target, fit_s, model = [], [], [], 0.0, None
        for fold, truth in zip(self.folds, self.truth):
            started = time.perf_counter()
            model = self.pipeline(params).fit(self.X.iloc[fold.train], self.y.iloc[fold.train])
            fit_s += time.perf_counter() - started
            pred = predict_rows(model, self.X, fold.test, allowed=self.outer_train)
            if not np.isfinite(pred).all():
                raise ValueError("non-finite predictions on an inner fold")
            metrics = evaluate(truth, pred)
            preds.append(pred)
            fold_rmse.append(float(metrics["mean"]["rmse"]))
            per_target.append([float(metrics[t]["rmse"]) for t in self.targets])
        costs = efficiency.measure(model, self.X, self.folds[-1].test, fit_s / len(self.folds)) \
            if measure_costs else {}
        target_rmse = dict(zip(self.targets, np.mean(per_target, axis=0).tolist()))
        return Evaluation(fold_rmse, target_rmse, aggregate(fold_rmse), preds, fit_s, costs)

    def fold_rmse(self, pred: np.ndarray, k: int) -> float:
        """RMSE (µm, mean over targets) of ``pred`` on inner fold ``k``'s validation rows."""
        return float(evaluate(self.truth[k], pred)["mean"]["rmse"])

    def score_predictions(self, preds: list[np.ndarray]) -> tuple[list[float], float]:
        """Per-fold RMSE (µm, mean over targets) and the aggregated score of given fold predictions."""
        rmse = [self.fold_rmse(p, k) for k, p in enumerate(preds)]
        return rmse, aggregate(rmse)
