"""Base classes for selectors and models, scikit-learn style.

Constructors only store parameters; ``fit`` learns (fitted attributes end in ``_``) and returns ``self``.
Inputs are pandas DataFrames indexed by time in s: temperatures in °C as ``X``, displacements in µm as ``y``
(one column per displacement channel). ``get_test_params`` gives cheap parameter sets for
``thermodrift.testing``; ``search_space`` gives the default Optuna search space (see ``search_space.py``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin


class Component(BaseEstimator):
    """Common surface of selectors and models."""

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        """At least one cheap parameter set for the conformance suite."""
        return [{}]

    @classmethod
    def search_space(cls) -> dict[str, dict[str, Any]]:
        """Default Optuna search space, e.g. ``{"alpha": {"type": "float", "low": 1e-6, "high": 1, "log": True}}``."""
        return {}


class Selector(Component):
    """Picks temperature-sensitive points. ``fit(X °C, y µm)`` sets ``selected_`` (a list of column names)."""

    def fit(self, X: pd.DataFrame, y: pd.DataFrame) -> "Selector":
        self.selected_ = list(self._select(X, y))
        if not self.selected_ or not set(self.selected_) <= set(X.columns):
            raise ValueError(f"{type(self).__name__} returned an invalid selection {self.selected_!r}")
        return self

    def transform(self, X: pd.DataFrame) -> pd.DataFrame:
        """The selected columns of ``X``."""
        return X[self.selected_]

    def fit_transform(self, X: pd.DataFrame, y: pd.DataFrame) -> pd.DataFrame:
        return self.fit(X, y).transform(X)

    def _select(self, X: pd.DataFrame, y: pd.DataFrame) -> list[str]:
        raise NotImplementedError


LAG_PREFIX = "lag1:"
RUN_STARTS = "run_starts_s"  # X.attrs key: times (s) at which the second and later runs of X start


def run_slices(X: pd.DataFrame) -> list[slice]:
    """Row slices of the independent runs in ``X`` (``X.attrs["run_starts_s"]``, times in s); one slice when X
    holds one run. A model with history computes its filters, states and windows per slice."""
    starts, n = X.attrs.get(RUN_STARTS) or (), len(X)
    if not len(starts) or n == 0:
        return [slice(0, n)]
    cuts = np.searchsorted(np.asarray(X.index, dtype=float), np.asarray(starts, dtype=float), side="left")
    edges = sorted({0, n, *(int(c) for c in cuts if 0 < c < n)})
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]


def per_run(X: pd.DataFrame, transform) -> np.ndarray:
    """``transform(part)`` of each run of ``X`` (see :func:`run_slices`), stacked in row order."""
    parts = run_slices(X)
    if len(parts) == 1:
        return transform(X)
    return np.concatenate([np.asarray(transform(X.iloc[s])) for s in parts])


def same_run(history: pd.DataFrame | None, t0_s: float | None = None) -> pd.DataFrame | None:
    """The rows of ``history`` in the run that holds time ``t0_s`` (s; default: history's last row's run), by
    ``history.attrs["run_starts_s"]``: what a model may carry into a prediction that starts at ``t0_s``."""
    starts = (history.attrs.get(RUN_STARTS) or ()) if history is not None else ()
    if not len(starts) or not len(history):
        return history
    t = np.asarray(history.index, dtype=float)
    t0 = t[-1] if t0_s is None else float(t0_s)
    begin = max((s for s in starts if s <= t0), default=-np.inf)
    return history.iloc[int(np.searchsorted(t, begin, side="left")):]


class ThermalModel(RegressorMixin, Component):
    """Maps temperatures (°C) to displacements (µm).

    ``predict(X)`` returns an array of shape (n_samples, n_displacement_channels) in µm. ``X`` holds the
    selected temperature columns, then the channels of every role in ``extra_input_roles`` (e.g. ``("speed",)``
    for a physics model; rpm), then, for models that read the previous measured displacement (a reference, not
    a compensation model: ``uses_target_history``), columns ``lag1:<channel>`` in µm. ``study.model_inputs``
    builds it.

    History and state, as a controller calls a model (the one contract of docs ``architecture.md``):
    ``predict(X, history)`` takes the input rows that precede ``X`` (same columns; never targets) and
    ``streamer(history).update(row)`` predicts one new row at a time, carrying its state; streaming over
    consecutive rows equals the batch prediction with history (``thermodrift.testing`` checks it for every
    model, within 1e-4 µm). A row is a pandas Series named by its time in s, as ``X.iloc[i]`` gives it.
    ``history_length`` says how many preceding rows a
    prediction depends on: 0 (memoryless, the default: history is ignored), k, or ``None`` (the whole past: a
    state). The base class handles all three by prediction over ``history + X``; a model whose state can be
    carried more cheaply overrides :meth:`streamer`.
    """

    uses_target_history: ClassVar[bool] = False
    extra_input_roles: ClassVar[tuple[str, ...]] = ()
    # Roles the model cannot run without (e.g. ("speed",)): a job refuses it, and AutoML leaves it out before
    # fitting, on a recording without a channel of each.
    requires_roles: ClassVar[tuple[str, ...]] = ()
    history_length: ClassVar[int | None] = 0
    sparse_targets: ClassVar[bool] = False  # a model with history that fits on NaN-free target rows itself

    def fit(self, X: pd.DataFrame, y: pd.DataFrame) -> "ThermalModel":
        """Fit on inputs ``X`` and targets ``y`` (µm). A sparse target (NaN between measurements) is fitted on the
        measured rows: a memoryless model sees only them; a model with history (``sparse_targets``) gets every
        input row, so its filters and windows run at full rate, and masks its loss."""
        y2 = _as_2d(y)
        self.n_features_in_ = X.shape[1]
        self.feature_names_in_ = np.asarray(X.columns, dtype=object)
        self.target_names_ = list(y.columns) if isinstance(y, pd.DataFrame) else [f"y{i}" for i in range(y2.shape[1])]
        measured = np.isfinite(y2).all(axis=1)
        if not measured.all():
            if measured.sum() < 2:
                raise ValueError(f"the target is measured in {int(measured.sum())} of {len(y2)} training rows; "
                                 "at least 2 are needed")
            if self.history_length == 0:
                X, y2 = X.iloc[np.flatnonzero(measured)], y2[measured]
            elif not self.sparse_targets:
                raise ValueError(f"{type(self).__name__} needs the target measured in every row (the target is "
                                 f"measured in {int(measured.sum())} of {len(y2)} rows)")
        self._fit(X, y2)
        return self

    def predict(self, X: pd.DataFrame, history: pd.DataFrame | None = None) -> np.ndarray:
        """Displacements (µm), shape (len(X), n_targets); ``history``: the input rows before ``X``. Each run of
        ``X`` (:func:`run_slices`) starts afresh; ``history`` counts only where it is in the first one's run."""
        if self.history_length != 0:
            parts = run_slices(X)
            if len(parts) > 1:
                return np.concatenate([self.predict(X.iloc[s], history if k == 0 else None)
                                       for k, s in enumerate(parts)])
            if history is not None and len(X):
                history = same_run(history, float(X.index[0]))
        past = self._relevant_history(history)
        if past is None or not len(past):
            return np.asarray(self._predict(X), dtype=float).reshape(len(X), -1)
        full = pd.concat([past[list(X.columns)], X])
        full.attrs = dict(X.attrs)
        out = np.asarray(self._predict(full), dtype=float).reshape(len(full), -1)
        return out[len(past):]

    def streamer(self, history: pd.DataFrame | None = None) -> "Streamer":
        """A one-row-at-a-time predictor that starts after ``history`` (see :class:`Streamer`)."""
        return Streamer(self, history)

    def _relevant_history(self, history: pd.DataFrame | None) -> pd.DataFrame | None:
        if history is None or self.history_length == 0:
            return None
        return history if self.history_length is None else history.iloc[-self.history_length:]

    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        raise NotImplementedError

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        raise NotImplementedError

    def export_state(self) -> dict[str, Any]:
        """The fitted model as data for :mod:`thermodrift.compensator`: a JSON-able tree (numpy arrays as leaves)
        with ``runtime`` (a runtime name), ``inputs``, ``targets`` and ``history_length`` (docs compensator.md).
        A model that cannot be exported says so; families override this."""
        raise NotImplementedError(f"model {type(self).__name__} cannot be exported: it has no export_state")


class Streamer:
    """Predicts one new input row per :meth:`update`, as a CNC controller calls a compensation model.

    The generic form keeps the rows the model's ``history_length`` needs and predicts the newest row with them
    as history, so it equals the batch prediction by construction; models with a cheaper state override
    ``ThermalModel.streamer``.
    """

    def __init__(self, model: ThermalModel, history: pd.DataFrame | None = None):
        self.model = model
        self.columns = list(model.feature_names_in_)
        past = model._relevant_history(same_run(history))
        self._rows = [] if past is None else [r for r in past[self.columns].to_numpy(dtype=float)]
        self._times = [] if past is None else [float(t) for t in past.index]
        self._attrs = dict(history.attrs) if history is not None else {}

    def values(self, row, columns: list[str] | None = None) -> np.ndarray:
        """``row``'s values of ``columns`` (default: the model's inputs) as floats. A Series (``X.iloc[i]``) is
        read by position, the positions looked up once per set of column labels: a label lookup costs more than
        a linear model's whole prediction. (Each ``X.iloc[i]`` carries a new Index object over the same labels,
        so the cache compares labels with ``Index.equals``, which is quick when they share their array.)"""
        columns = self.columns if columns is None else columns
        index = getattr(row, "index", None)
        if index is not None and hasattr(row, "to_numpy"):
            cache = self.__dict__.setdefault("_positions", {})
            hit = cache.get(id(columns))
            if hit is None or not (hit[0] is index or hit[0].equals(index)):
                hit = cache[id(columns)] = (index, np.asarray(index.get_indexer(columns)), columns)
            pos = hit[1]
            if (pos >= 0).all():
                return row.to_numpy(dtype=float)[pos]
        return np.array([float(row[c]) for c in columns])

    def update(self, row) -> np.ndarray:
        """Displacement (µm) per target for one new input ``row`` (a Series named by its time in s, or a
        mapping column -> value)."""
        x = self.values(row)[None, :]
        name = getattr(row, "name", None)
        t = float(name) if isinstance(name, (int, float, np.number)) else float(len(self._times))
        if self.model.history_length == 0:
            return self.model.predict(self._frame(x, [t]))[0]
        self._rows.append(x[0])
        self._times.append(t)
        if self.model.history_length is not None:
            keep = max(0, len(self._rows) - self.model.history_length - 1)
            del self._rows[:keep], self._times[:keep]
        frame = self._frame(np.asarray(self._rows), self._times)
        return self.model.predict(frame.iloc[-1:], history=frame.iloc[:-1])[0]

    def _frame(self, x: np.ndarray, times: list[float]) -> pd.DataFrame:
        frame = pd.DataFrame(x, columns=self.columns, index=pd.Index(times, name="time_s"))
        frame.attrs = dict(self._attrs)
        return frame


def _as_2d(y: pd.DataFrame | np.ndarray) -> np.ndarray:
    arr = np.asarray(y, dtype=float)
    return arr.reshape(len(arr), -1)
