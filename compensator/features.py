"""The feature stage: raw temperatures (°C), first-order-filtered temperatures and drive heat terms, numpy only.

Thermal drift follows the heat flow, which lags the measured temperatures and the drives. A feature stage turns
the raw input columns (in ``inputs`` order: the temperature columns, then the drive columns) into

* the raw temperatures (°C) and the drive heat terms ``(|v| / v_ref)^p`` for every power ``p`` (``v``: spindle
  speed in rpm or cutting power in W; ``v_ref``: the largest absolute training value), then
* the same columns low-pass filtered with each time constant ``tau`` of ``taus_s`` (s), tau-major: every
  temperature at the first tau, ..., then every drive term at the first tau, ...

Each filter is the exact discretisation of dx/dt = (u − x) / tau at the sampling interval ``sample_s`` (s):
``x ← a·x + (1 − a)·u`` with ``a = exp(−sample_s / tau)``, so a controller must call the stage at that interval.
Temperature filters start at the first input row, drive filters at rest (a machine starts cold and stopped).
That state is the stage's memory: :meth:`FeatureStage.transform` runs the filters through ``history`` first, and
:meth:`FeatureStage.stream` carries it, one row per ``update`` (a few numpy operations), equal to the batch.

``to_state()`` gives a JSON-able dict (numpy arrays as leaves) that ``from_state`` rebuilds; it is the
``"features"`` entry of a pipeline's ``export_state()``.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

DRIVE_ROLES = ("speed", "cutting_power")
FORMAT = "features/1"


class FeatureStage:
    """Raw temperatures, drive heat terms and their first-order filters (see the module docstring).

    ``temperatures`` and ``drives`` are the input column names (their order is ``inputs``); ``drive_ref`` is one
    positive scale per drive column; ``taus_s`` may be empty (raw temperatures and drive terms only).
    """

    def __init__(self, temperatures: Sequence[str], drives: Sequence[str], taus_s: Sequence[float],
                 powers: Sequence[float], sample_s: float, drive_ref: Sequence[float] | None = None):
        self.temperatures = [str(c) for c in temperatures]
        self.drives = [str(c) for c in drives]
        self.taus_s = np.asarray(taus_s, dtype=float).reshape(-1)
        self.powers = np.asarray(powers, dtype=float).reshape(-1)
        self.sample_s = float(sample_s)
        self.drive_ref = (np.ones(len(self.drives)) if drive_ref is None
                          else np.asarray(drive_ref, dtype=float).reshape(-1))
        if len(self.drive_ref) != len(self.drives) or (self.drive_ref <= 0).any():
            raise ValueError("drive_ref needs one positive value per drive column")
        if (self.taus_s <= 0).any() or self.sample_s <= 0:
            raise ValueError("taus_s and sample_s must be positive (s)")
        if self.drives and not len(self.powers):
            raise ValueError("drive heat terms need at least one power")
        self.decay = np.exp(-self.sample_s / self.taus_s)
        n_t, n_terms = len(self.temperatures), len(self.drives) * len(self.powers)
        # Per filtered column (tau-major within temperatures, then within drive terms): its decay.
        self._a = np.concatenate([np.repeat(self.decay, n_t), np.repeat(self.decay, n_terms)])
        self._b = 1.0 - self._a

    # ------------------------------------------------------------------------------------------------ building
    @classmethod
    def fit(cls, values: np.ndarray, columns: Sequence[str], roles: dict[str, str], time_s: np.ndarray,
            taus_s: Sequence[float], powers: Sequence[float]) -> "FeatureStage":
        """A stage for the training rows ``values`` (columns ``columns``; ``roles`` maps a column to its role, drive
        roles: speed, cutting_power): ``v_ref`` per drive column and the median sampling interval of ``time_s``."""
        values = np.asarray(values, dtype=float)
        columns = [str(c) for c in columns]
        drives = [c for c in columns if roles.get(c) in DRIVE_ROLES]
        temps = [c for c in columns if c not in drives]
        drive = values[:, [columns.index(c) for c in drives]] if drives else np.zeros((len(values), 0))
        peak = np.abs(drive).max(axis=0) if len(drive) else np.ones(len(drives))
        step = np.diff(np.asarray(time_s, dtype=float))
        sample_s = float(np.median(step)) if len(step) and np.median(step) > 0 else 1.0
        return cls(temps, drives, taus_s, powers, sample_s, np.where(peak > 0, peak, 1.0))

    @property
    def inputs(self) -> list[str]:
        """The columns the stage reads, in the order ``transform`` and ``update`` expect them."""
        return self.temperatures + self.drives

    @property
    def names(self) -> list[str]:
        """Output column names: ``T``, ``speed^2``, ``T|f300s``, ``speed^2|f300s`` (tau-major)."""
        terms = [f"{c}^{p:g}" for p in self.powers for c in self.drives]
        filtered = [f"{c}|f{tau:g}s" for group in (self.temperatures, terms) for tau in self.taus_s for c in group]
        return self.temperatures + terms + filtered

    # ------------------------------------------------------------------------------------------------ arithmetic
    def drive_terms(self, drive: np.ndarray) -> np.ndarray:
        """``(|v| / v_ref)^p`` per row, power-major (all drives at the first power, then the next)."""
        if not self.drives:
            return np.zeros((len(drive), 0))
        scaled = np.abs(drive) / self.drive_ref
        return np.hstack([scaled ** p for p in self.powers.tolist()])

    def initial_state(self, temps0: np.ndarray) -> np.ndarray:
        """Filter state before the first row: temperature filters at ``temps0`` (°C), drive filters at rest."""
        n_terms = len(self.drives) * len(self.powers)
        return np.concatenate([np.tile(temps0, len(self.decay)), np.zeros(n_terms * len(self.decay))])

    def _split(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values = np.asarray(values, dtype=float).reshape(len(values), -1)
        if values.shape[1] != len(self.inputs):
            raise ValueError(f"the feature stage reads {len(self.inputs)} columns {self.inputs}, "
                             f"got {values.shape[1]}")
        n_t = len(self.temperatures)
        return values[:, :n_t], self.drive_terms(values[:, n_t:])

    def _filter_input(self, temps: np.ndarray, terms: np.ndarray) -> np.ndarray:
        n = len(self.decay)
        return np.hstack([np.tile(temps, (1, n)), np.tile(terms, (1, n))])

    def transform(self, values: np.ndarray, history: np.ndarray | None = None) -> np.ndarray:
        """Features of the rows ``values`` (n, len(inputs)); ``history``: the input rows before them (the filters
        start at history's first row, else at the first row of ``values``)."""
        values = np.asarray(values, dtype=float).reshape(len(values), -1)
        if history is not None and len(history):
            return self.transform(np.vstack([np.asarray(history, dtype=float), values]))[len(history):]
        temps, terms = self._split(values)
        u = self._filter_input(temps, terms)
        filtered = np.empty_like(u)
        state = self.initial_state(temps[0]) if len(temps) else np.zeros(u.shape[1])
        a, b = self._a, self._b
        # A vectorised recursion over columns: scipy.signal.lfilter would take one call per decay value, and
        # this module stays numpy-only (the compensator runs it on a controller).
        for i in range(len(u)):
            state = a * state + b * u[i]
            filtered[i] = state
        return np.hstack([temps, terms, filtered])

    def stream(self, history: np.ndarray | None = None) -> "FeatureStream":
        """A one-row-at-a-time transform that starts after the input rows ``history``."""
        return FeatureStream(self, history)

    # ------------------------------------------------------------------------------------------------ state
    def to_state(self) -> dict[str, Any]:
        """A JSON-able description (numpy arrays as leaves) that :meth:`from_state` rebuilds."""
        return {"format": FORMAT, "temperatures": list(self.temperatures), "drives": list(self.drives),
                "taus_s": self.taus_s.copy(), "powers": self.powers.copy(), "sample_s": self.sample_s,
                "drive_ref": self.drive_ref.copy(), "names": self.names}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> "FeatureStage":
        if state.get("format") != FORMAT:
            raise ValueError(f"not a feature stage state (format {state.get('format')!r}, expected {FORMAT!r})")
        return cls(state["temperatures"], state["drives"], state["taus_s"], state["powers"], state["sample_s"],
                   state["drive_ref"])

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FeatureStage):
            return NotImplemented
        mine, theirs = self.to_state(), other.to_state()
        return all(np.array_equal(mine[k], theirs[k]) if isinstance(mine[k], np.ndarray) else mine[k] == theirs[k]
                   for k in mine)

    __hash__ = None  # mutable arrays inside


class FeatureStream:
    """Carries a stage's filter state; ``update(values)`` gives one row's features as the batch does."""

    def __init__(self, stage: FeatureStage, history: np.ndarray | None = None):
        self.stage = stage
        self.state: np.ndarray | None = None
        n_fixed = len(stage.temperatures) + len(stage.drives) * len(stage.powers)
        if history is not None and len(history):
            self.state = stage.transform(history)[-1, n_fixed:].copy()

    def update(self, values: np.ndarray) -> np.ndarray:
        """Features (1-D, ``stage.names`` order) of one new input row ``values`` (``stage.inputs`` order)."""
        temps, terms = self.stage._split(np.asarray(values, dtype=float).reshape(1, -1))
        if self.state is None:
            self.state = self.stage.initial_state(temps[0])
        u = self.stage._filter_input(temps, terms)[0]
        self.state = self.stage._a * self.state + self.stage._b * u
        return np.concatenate([temps[0], terms[0], self.state])
