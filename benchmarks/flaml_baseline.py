"""FLAML, the AutoML the benchmarks compare ``thermodrift automl`` with (``pip install -e ".[compare]"``; CI does
not install it): one regression fit per target on one core within a time budget, validated on the last 25 % of
its training rows in time order, as a user would run it on a drift recording."""

from __future__ import annotations

import importlib.util
import warnings

import numpy as np


def available() -> bool:
    """Whether FLAML is installed."""
    return importlib.util.find_spec("flaml") is not None


def fit_predict(X_train: np.ndarray, y_train: np.ndarray, X_test: np.ndarray, seconds: float,
                seed: int) -> np.ndarray:
    """FLAML's predictions for ``X_test`` after a search of ``seconds`` (at least 1 s) on the training rows."""
    from flaml import AutoML

    model = AutoML()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.fit(X_train, y_train, task="regression", metric="rmse", n_jobs=1, time_budget=max(1.0, seconds),
                  eval_method="holdout", split_type="time", split_ratio=0.25, seed=seed, verbose=0)
    return model.predict(X_test)
