"""Model ``transfer_function``: the industrial anchor, a linear transfer-function model as CNCs run it today.

Displacement (µm) is a linear read-out of first-order-filtered inputs (Mares et al., Precision Engineering 2020
use the same structure inside the controller): every temperature (°C) raw and low-pass filtered with time
constants ``tau`` geometric between ``tau_min_s`` and ``tau_max_s``, and every drive input (spindle speed, rpm;
cutting power, W) as heat terms (v / v_ref)^p for p in ``powers``, raw and filtered with the same constants.
The read-out is ridge regression on standardised features; its strength is the one of ``alphas`` with the
lowest RMSE on an inner validation fold (the last ``inner_fraction`` of the training rows), then refit on all.

The filters are the exact discretisation of dx/dt = (u − x)/tau at the training sampling interval (s), so the
model assumes the controller calls it at that interval. They start from the first input row (temperatures) and
from rest (drive terms: a machine starts cold and stopped). That state is the model's memory
(``history_length = None``): ``predict(X, history)`` runs the filters through ``history`` first, and
:meth:`TransferFunction.streamer` carries it in a few numpy operations per row (≤ 0.05 ms).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pandas as pd
from sklearn.linear_model import Ridge

from thermodrift.core.components import ThermalModel
from thermodrift.core.hookspecs import hookimpl

DRIVE_ROLES = ("speed", "cutting_power")


class TransferFunction(ThermalModel):
    """First-order-filtered temperatures and drive heat terms with a ridge read-out (see the module docstring)."""

    extra_input_roles: ClassVar[tuple[str, ...]] = ("speed", "cutting_power", "ambient")
    history_length: ClassVar[int | None] = None

    def __init__(self, tau_min_s: float = 300.0, tau_max_s: float = 14400.0, n_taus: int = 4,
                 powers: tuple = (1.0, 2.0), alphas: tuple = (1e-4, 1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3),
                 inner_fraction: float = 0.25):
        self.tau_min_s = tau_min_s
        self.tau_max_s = tau_max_s
        self.n_taus = n_taus
        self.powers = powers
        self.alphas = alphas
        self.inner_fraction = inner_fraction

    @classmethod
    def get_test_params(cls):
        return [{}, {"n_taus": 2, "powers": (1.5,), "alphas": (0.1, 10.0)}]

    @classmethod
    def search_space(cls):
        return {"tau_min_s": {"type": "float", "low": 60.0, "high": 1800.0, "log": True},
                "tau_max_s": {"type": "float", "low": 3600.0, "high": 43200.0, "log": True},
                "n_taus": {"type": "int", "low": 1, "high": 6}}

    # ------------------------------------------------------------------------------------------------ fitting
    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        if not 0 < self.tau_min_s <= self.tau_max_s or self.n_taus < 1:
            raise ValueError("need 0 < tau_min_s <= tau_max_s and n_taus >= 1")
        if not 0 < self.inner_fraction < 1 or not len(self.alphas):
            raise ValueError("inner_fraction must be in (0, 1) and alphas non-empty")
        roles = X.attrs.get("roles", {})
        cols = list(X.columns)
        self.drive_columns_ = [c for c in cols if roles.get(c) in DRIVE_ROLES]
        self.temperature_columns_ = [c for c in cols if c not in self.drive_columns_]
        drive = X[self.drive_columns_].to_numpy(dtype=float)
        self.drive_ref_ = np.where(np.abs(drive).max(axis=0) > 0, np.abs(drive).max(axis=0), 1.0) if len(drive) \
            else np.ones(len(self.drive_columns_))
        step = np.diff(np.asarray(X.index, dtype=float))
        self.sample_s_ = float(np.median(step)) if len(step) and np.median(step) > 0 else 1.0
        self.taus_s_ = np.geomspace(self.tau_min_s, self.tau_max_s, self.n_taus)
        self.decay_ = np.exp(-self.sample_s_ / self.taus_s_)
        F = self._features(X)
        mean, scale = F.mean(axis=0), F.std(axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        Z = (F - mean) / scale
        cut = int(round(len(Z) * (1 - self.inner_fraction)))
        if 2 <= cut <= len(Z) - 1:
            scores = [np.sqrt(np.mean((Ridge(alpha=a).fit(Z[:cut], y[:cut]).predict(Z[cut:]) - y[cut:]) ** 2))
                      for a in self.alphas]
            self.alpha_ = float(self.alphas[int(np.argmin(scores))])
        else:
            self.alpha_ = float(np.median(self.alphas))
        ridge = Ridge(alpha=self.alpha_).fit(Z, y)
        coef = np.atleast_2d(ridge.coef_)  # (k, features)
        # The standardisation is folded into the read-out, so prediction is one affine map of the features.
        self.weights_ = coef / scale
        self.intercept_ = np.atleast_1d(ridge.intercept_) - self.weights_ @ mean

    # ------------------------------------------------------------------------------------------------ features
    def _drive_terms(self, drive: np.ndarray) -> np.ndarray:
        scaled = np.abs(drive) / self.drive_ref_
        return np.hstack([scaled ** p for p in self.powers]) if drive.shape[1] else drive

    def _initial_state(self, temps0: np.ndarray) -> np.ndarray:
        n_drive = len(self.drive_columns_) * len(self.powers)
        return np.concatenate([np.tile(temps0, len(self.decay_)), np.zeros(n_drive * len(self.decay_))])

    def _layout(self, temps: np.ndarray, terms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Filter inputs per row, stacked (tau-major per group), and the matching per-column decays."""
        u = np.hstack([np.tile(temps, (1, len(self.decay_))), np.tile(terms, (1, len(self.decay_)))])
        a = np.concatenate([np.repeat(self.decay_, temps.shape[1]), np.repeat(self.decay_, terms.shape[1])])
        return u, a

    def _features(self, X: pd.DataFrame) -> np.ndarray:
        temps = X[self.temperature_columns_].to_numpy(dtype=float)
        terms = self._drive_terms(X[self.drive_columns_].to_numpy(dtype=float))
        u, a = self._layout(temps, terms)
        state = self._initial_state(temps[0]) if len(temps) else np.zeros(u.shape[1])
        filtered = np.empty_like(u)
        # A vectorised recursion over columns; scipy.signal.lfilter would need one call per decay value.
        for i in range(len(u)):
            state = a * state + (1 - a) * u[i]
            filtered[i] = state
        return np.hstack([temps, terms, filtered])

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        return self._features(X) @ self.weights_.T + self.intercept_

    def streamer(self, history: pd.DataFrame | None = None) -> "TransferFunctionStreamer":
        return TransferFunctionStreamer(self, history)

    def export_state(self) -> dict:
        """Runtime ``transfer_function``: column groups, drive references, filter decays and the read-out."""
        return {"runtime": "transfer_function", "inputs": [str(c) for c in self.feature_names_in_],
                "targets": list(self.target_names_), "history_length": None,
                "temperature_columns": list(self.temperature_columns_), "drive_columns": list(self.drive_columns_),
                "drive_ref": np.asarray(self.drive_ref_, dtype=float), "powers": np.asarray(self.powers, dtype=float),
                "decay": self.decay_, "taus_s": self.taus_s_, "sample_s": self.sample_s_,
                "weights": self.weights_, "intercept": self.intercept_}


class TransferFunctionStreamer:
    """Carries the filter state; ``update(row)`` costs a handful of small numpy operations."""

    def __init__(self, model: TransferFunction, history: pd.DataFrame | None = None):
        m = model
        self.temps, self.drives = list(m.temperature_columns_), list(m.drive_columns_)
        self.powers = np.asarray(m.powers, dtype=float)
        n_taus = len(m.decay_)
        self.n_t, self.n_d = len(self.temps), len(self.drives)
        self.ref = m.drive_ref_
        self.a = np.concatenate([np.repeat(m.decay_, self.n_t), np.repeat(m.decay_, self.n_d * len(self.powers))])
        self.b = 1.0 - self.a
        self.n_taus = n_taus
        W = m.weights_
        n_terms = self.n_d * len(self.powers)
        self.w_temp, self.w_terms = W[:, :self.n_t], W[:, self.n_t:self.n_t + n_terms]
        self.w_state, self.c = W[:, self.n_t + n_terms:], m.intercept_
        self.model, self.state = m, None
        if history is not None and len(history):
            F = m._features(history)
            self.state = F[-1, self.n_t + n_terms:].copy()

    def update(self, row) -> np.ndarray:
        """Displacement (µm) per target for one new input ``row`` (a mapping column -> value)."""
        temps = np.array([row[c] for c in self.temps], dtype=float)
        if self.n_d:
            drive = np.abs(np.array([row[c] for c in self.drives], dtype=float)) / self.ref
            terms = np.power.outer(drive, self.powers).T.ravel()  # power-major, as np.hstack over powers
        else:
            terms = np.zeros(0)
        if self.state is None:
            self.state = self.model._initial_state(temps)
        u = np.concatenate([np.tile(temps, self.n_taus), np.tile(terms, self.n_taus)])
        self.state = self.a * self.state + self.b * u
        return self.w_temp @ temps + self.w_terms @ terms + self.w_state @ self.state + self.c


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "transfer_function", TransferFunction)
