"""Models ``pipeline`` and ``ensemble``: what ``thermodrift automl`` chooses, as registered models.

A ``pipeline`` is a selector (registry name and parameters; ``"all"`` keeps every temperature channel), an
optional feature stage (:class:`thermodrift.compensator.features.FeatureStage`: raw temperatures °C, filtered
temperatures and drive heat terms) and an inner model (registry name and parameters). It reads every input
channel (``extra_input_roles``: temperatures, ambient, coolant, speed rpm, cutting power W) and, inside ``fit``,
selects on the training rows, builds the inner model's inputs exactly as a study does (the selected temperatures
plus the inner model's own ``extra_input_roles``; with a feature stage, the stage's features of the selected
temperatures and the drive channels instead) and fits it. Physics families, which read raw channels by role
(their ``extra_input_roles`` name ``speed``), take no feature stage.

An ``ensemble`` is a weighted sum of fitted pipelines (weights sum to 1), e.g. the greedy ensemble AutoML builds.

Both stream exactly: the streamer carries the feature stage's filter state and the inner model's streamer.
Stored (pickle, ``thermodrift.core.artifacts``) with the inner model as registry name, parameters and fitted
state, so a third-party inner model is logged and reloaded like any model. ``export_state()`` follows the
compensator's export contract (runtimes ``pipeline`` and ``ensemble``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pandas as pd

from thermodrift.compensator.features import DRIVE_ROLES, FeatureStage
from thermodrift.core import registry
from thermodrift.core.components import RUN_STARTS, ThermalModel, per_run, same_run
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.recording import INPUT_ROLES as SELECTABLE_ROLES  # °C, W/m², W: what a selector picks from

INPUT_ROLES = (*SELECTABLE_ROLES, *DRIVE_ROLES)


def pack(model: ThermalModel, name: str) -> dict[str, Any]:
    """A fitted registry model as plain data: its name, constructor parameters and fitted state."""
    params = model.get_params(deep=False)
    return {"name": name, "params": params,
            "state": {k: v for k, v in model.__getstate__().items() if k not in params}}


def unpack(packed: dict[str, Any]) -> ThermalModel:
    """The model :func:`pack` described, rebuilt through the registry."""
    model = registry.create("model", packed["name"], **packed["params"])
    model.__setstate__(dict(packed["state"]))
    return model


class Pipeline(ThermalModel):
    """Selector → optional feature stage → inner model (see the module docstring).

    ``model``/``model_params``: the inner model's registry name and parameters; ``selector``/``selector_params``:
    the selector's; ``features``: None (the inner model reads the selected channels) or
    ``{"taus_s": [s, ...], "powers": [p, ...]}``; ``random_state`` seeds the components that take a seed.
    """

    automl_cost = "skip"  # AutoML builds pipelines itself

    @property
    def refits_cheaply(self) -> bool:
        """A pipeline refits as cheaply as the model inside it (its class's ``refits_cheaply``)."""
        return bool(getattr(registry.get("model", self.model).factory, "refits_cheaply", False))

    extra_input_roles: ClassVar[tuple[str, ...]] = INPUT_ROLES
    sparse_targets: ClassVar[bool] = True  # selects on the measured rows; features and inner model at full rate

    def __init__(self, model: str = "mlr", model_params: dict | None = None, selector: str = "all",
                 selector_params: dict | None = None, features: dict | None = None, random_state: int = 0):
        self.model = model
        self.model_params = model_params
        self.selector = selector
        self.selector_params = selector_params
        self.features = features
        self.random_state = random_state

    @property
    def history_length(self) -> int | None:  # type: ignore[override]
        """None (a state) with a feature stage, else the inner model's."""
        if self.features is not None:
            return None
        if "inner_" in self.__dict__:
            return _inner(self).history_length
        return registry.get("model", self.model).factory(**(self.model_params or {})).history_length

    @classmethod
    def get_test_params(cls):
        return [{"model": "mlr"},
                {"model": "mlr", "model_params": {"alpha": 1.0}, "selector": "correlation_top_k",
                 "selector_params": {"k": 2}, "features": {"taus_s": [600.0, 3000.0], "powers": [1.0, 2.0]}},
                {"model": "transfer_function", "model_params": {"n_taus": 2}}]

    # ------------------------------------------------------------------------------------------------ fitting
    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        roles = dict(X.attrs.get("roles") or {c: "temperature" for c in X.columns})
        cls = registry.get("model", self.model).factory
        if getattr(cls, "uses_target_history", False):
            raise ValueError(f"model {self.model!r} reads the measured target: a reference, not a pipeline's model")
        candidates = [c for c in X.columns if roles.get(c, "temperature") in SELECTABLE_ROLES]
        if not candidates:
            raise ValueError("a pipeline needs at least one temperature or heat-input channel among its inputs")
        targets = pd.DataFrame(y, index=X.index, columns=self.target_names_)
        if self.selector == "all":
            self.selected_ = list(candidates)
        else:
            factory = registry.get("selector", self.selector).factory
            sel = registry.create("selector", self.selector,
                                  **registry.with_seed(factory, dict(self.selector_params or {}), self.random_state))
            measured = np.flatnonzero(np.isfinite(y).all(axis=1))  # a sparse target: select on the measured rows
            self.selected_ = list(sel.fit(X[candidates].iloc[measured], targets.iloc[measured]).selected_)
        drives = [c for c in X.columns if roles.get(c) in DRIVE_ROLES]
        if self.features is not None:
            if "speed" in getattr(cls, "extra_input_roles", ()):
                raise ValueError(f"model {self.model!r} reads raw channels by role (speed among its "
                                 "extra_input_roles): give it features=None")
            unknown = sorted(set(self.features) - {"taus_s", "powers"})
            if unknown:
                raise ValueError(f"features takes taus_s and powers, not {unknown}")
            columns = self.selected_ + drives
            self.features_ = FeatureStage.fit(X[columns].to_numpy(dtype=float), columns, roles,
                                              np.asarray(X.index, dtype=float),
                                              self.features.get("taus_s", ()), self.features.get("powers", (1.0,)))
            self.inner_columns_ = self.features_.inputs
        else:
            self.features_ = None
            extra = [c for role in getattr(cls, "extra_input_roles", ()) for c in X.columns
                     if roles.get(c) == role and c not in self.selected_]
            self.inner_columns_ = self.selected_ + list(dict.fromkeys(extra))
        self.input_roles_ = {c: roles.get(c, "temperature") for c in self.inner_columns_}
        inner = registry.create("model", self.model, **registry.with_seed(cls, dict(self.model_params or {}), self.random_state))
        self.inner_ = inner.fit(self._inner_frame(X), targets)

    def _inner_frame(self, X: pd.DataFrame, history: pd.DataFrame | None = None) -> pd.DataFrame:
        """The inner model's input rows for ``X`` (features run through ``history`` first)."""
        raw = X[self.inner_columns_]
        runs = {RUN_STARTS: X.attrs[RUN_STARTS]} if X.attrs.get(RUN_STARTS) else {}
        if self.features_ is None:
            frame = raw.copy()
            frame.attrs = {"roles": dict(self.input_roles_), **runs}
            return frame
        if history is not None:
            past = history[self.inner_columns_].to_numpy(dtype=float)
            F = self.features_.transform(raw.to_numpy(dtype=float), past)
        else:  # each run's filters start at its own first row
            F = per_run(raw, lambda part: self.features_.transform(part.to_numpy(dtype=float)))
        return self._feature_frame(F, X.index, runs)

    def _feature_frame(self, F: np.ndarray, index: pd.Index, runs: dict | None = None) -> pd.DataFrame:
        frame = pd.DataFrame(F, index=index, columns=self.features_.names)
        frame.attrs = {"roles": {c: "temperature" for c in frame.columns}, **(runs or {})}
        return frame

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        return _inner(self).predict(self._inner_frame(X))

    def streamer(self, history: pd.DataFrame | None = None) -> "PipelineStreamer":
        return PipelineStreamer(self, history)

    def fitted_models(self) -> list[ThermalModel]:
        """The fitted inner model (its parameters are the pipeline's; ``core.efficiency`` counts them)."""
        return [_inner(self)]

    # ------------------------------------------------------------------------------------------------ storing
    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        if isinstance(state.get("inner_"), ThermalModel):
            state["inner_"] = pack(state["inner_"], self.model)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        super().__setstate__(state)
        if "inner_" in self.__dict__:
            _inner(self)

    def export_state(self) -> dict[str, Any]:
        """The compensator's ``pipeline`` runtime state (see the export contract)."""
        return {"runtime": "pipeline", "inputs": list(self.feature_names_in_), "targets": list(self.target_names_),
                "history_length": self.history_length, "selected": list(self.inner_columns_),
                "features": None if self.features_ is None else self.features_.to_state(),
                "model": _inner(self).export_state()}


def _inner(pipeline: Pipeline) -> ThermalModel:
    """The fitted inner model, rebuilt from its stored form (name, parameters, state) the first time it is read
    after loading (``thermodrift.core.artifacts`` restores attributes without ``__setstate__``)."""
    inner = pipeline.__dict__["inner_"]
    if isinstance(inner, dict):
        inner = pipeline.__dict__["inner_"] = unpack(inner)
    return inner


class PipelineStreamer:
    """Carries the feature stage's filter state and the inner model's streamer; ``update(row)`` → µm per target."""

    def __init__(self, pipeline: Pipeline, history: pd.DataFrame | None = None):
        self.pipeline = pipeline
        self.columns = list(pipeline.inner_columns_)
        inner = _inner(pipeline)
        history = same_run(history)
        past = history if history is not None and len(history) else None
        if pipeline.features_ is None:
            self.stream = None
            frame = None if past is None else pipeline._inner_frame(past)
        else:
            values = None if past is None else past[self.columns].to_numpy(dtype=float)
            self.stream = pipeline.features_.stream(values)
            self.names = pipeline.features_.names
            frame = None
            if past is not None and inner.history_length != 0:
                frame = pipeline._feature_frame(pipeline.features_.transform(values), past.index)
        self.inner = inner.streamer(frame)

    def update(self, row) -> np.ndarray:
        """Displacement (µm) per target for one new input ``row`` (a Series named by its time in s, or a mapping)."""
        values = np.array([float(row[c]) for c in self.columns])
        name = getattr(row, "name", None)
        if self.stream is None:
            return self.inner.update(pd.Series(values, index=self.columns, name=name))
        return self.inner.update(pd.Series(self.stream.update(values), index=self.names, name=name))


class Ensemble(ThermalModel):
    """A weighted sum of pipelines: ``members`` are pipeline parameter dicts, ``weights`` their weights (≥ 0,
    normalised to sum 1)."""

    automl_cost = "skip"  # AutoML builds ensembles itself

    @property
    def refits_cheaply(self) -> bool:
        """An ensemble refits cheaply when every member does."""
        return all(Pipeline(**m).refits_cheaply for m in self.members or [])

    extra_input_roles: ClassVar[tuple[str, ...]] = INPUT_ROLES
    sparse_targets: ClassVar[bool] = True  # its member pipelines are

    def __init__(self, members: list | None = None, weights: list | None = None, random_state: int = 0):
        self.members = members
        self.weights = weights
        self.random_state = random_state

    @property
    def history_length(self) -> int | None:  # type: ignore[override]
        lengths = [m.history_length for m in _members(self)] or [None]
        return None if any(n is None for n in lengths) else max(lengths)

    @classmethod
    def get_test_params(cls):
        return [{"members": [{"model": "mlr"},
                             {"model": "mlr", "features": {"taus_s": [900.0], "powers": [1.0]}}],
                 "weights": [0.5, 0.5]}]

    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        members = list(self.members or [])
        w = np.asarray(self.weights if self.weights is not None else np.ones(len(members)), dtype=float)
        if not members or len(w) != len(members) or (w < 0).any() or w.sum() <= 0:
            raise ValueError("an ensemble needs members and one non-negative weight per member (sum > 0)")
        self.weights_ = w / w.sum()
        targets = pd.DataFrame(y, index=X.index, columns=self.target_names_)
        self.members_ = [Pipeline(**registry.with_seed(Pipeline, m, self.random_state)).fit(X, targets) for m in members]

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        return sum(w * m.predict(X) for w, m in zip(self.weights_, _members(self)))

    def predict(self, X: pd.DataFrame, history: pd.DataFrame | None = None) -> np.ndarray:
        """Weighted member predictions (µm), each member with the history it needs."""
        if not hasattr(self, "members_"):
            return super().predict(X, history)
        return sum(w * m.predict(X, history) for w, m in zip(self.weights_, _members(self)))

    def streamer(self, history: pd.DataFrame | None = None) -> "EnsembleStreamer":
        return EnsembleStreamer(self, history)

    def fitted_models(self) -> list[ThermalModel]:
        """The fitted member pipelines (``core.efficiency`` counts their parameters)."""
        return list(_members(self))

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        if "members_" in state:
            state["members_"] = [pack(m, "pipeline") if isinstance(m, Pipeline) else m for m in state["members_"]]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        super().__setstate__(state)
        _members(self)

    def export_state(self) -> dict[str, Any]:
        """The compensator's ``ensemble`` runtime state (see the export contract)."""
        return {"runtime": "ensemble", "inputs": list(self.feature_names_in_), "targets": list(self.target_names_),
                "history_length": self.history_length, "weights": [float(w) for w in self.weights_],
                "members": [m.export_state() for m in _members(self)]}


def _members(ensemble: Ensemble) -> list[Pipeline]:
    """The fitted member pipelines, rebuilt from their stored form the first time they are read after loading."""
    members = ensemble.__dict__.get("members_", [])
    if any(isinstance(m, dict) for m in members):
        members = ensemble.__dict__["members_"] = [unpack(m) if isinstance(m, dict) else m for m in members]
    return members


class EnsembleStreamer:
    """One streamer per member; ``update(row)`` is their weighted sum (µm)."""

    def __init__(self, ensemble: Ensemble, history: pd.DataFrame | None = None):
        self.weights = ensemble.weights_
        self.streamers = [m.streamer(history) for m in _members(ensemble)]

    def update(self, row) -> np.ndarray:
        return sum(w * s.update(row) for w, s in zip(self.weights, self.streamers))


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "pipeline", Pipeline)
    registry.add("model", "ensemble", Ensemble)
