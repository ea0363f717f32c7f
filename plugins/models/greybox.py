"""Model ``greybox``: the stochastic grey-box as a model family — a linear RC network as a stochastic differential
equation, fitted by maximum likelihood through the continuous–discrete Kalman filter
(:mod:`thermodrift.core.physics.stochastic`), predicting from the inputs only.

Per target:

* on a building (inputs with the roles ``ambient`` and ``heating``, and ``solar_irradiance`` where there is one):
  the building RC library's network — with ``structure="select"`` the forward selection from the one-state model
  ``building_ti`` (likelihood-ratio tests, :func:`~thermodrift.core.physics.stochastic.selection.forward_select`),
  with ``structure="Ti"`` the one-state model itself; time in hours, heat in the heating input's unit;
* on any other recording (a machine tool: temperatures °C to a displacement µm): one state x with
  τ dx = (−x + Σ g_j u_j + g₀) dt + σ dW over every input u_j, y = x + e — the same estimator on the smallest
  network that has the target's own dynamics and offset (what the conformance suite fits; AutoML and jobs
  leave the family out where there is no heating channel, ``requires_roles``).

Prediction is the deterministic simulation of the fitted SDE (its mean) over the inputs, from the equilibrium of
the first row's inputs (so a prediction depends on no later row): no measured target is read, so a one-step and a 24 h-ahead
prediction are the same. The whole past is the state (``history_length = None``): ``predict(X, history)``
simulates through ``history`` first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd

from thermodrift.core.components import ThermalModel
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics import stochastic as sto
from thermodrift.core.physics.stochastic.selection import forward_select, ti_start

BUILDING_ROLES = ("ambient", "solar_irradiance", "heating")
STRUCTURES = ("select", "Ti")


@dataclass(frozen=True)
class FirstOrder:
    """The generic network: one state per target over ``inputs`` plus a constant (a :mod:`~.stochastic.fit`
    model: ``name``, ``parameters``, ``system``). Time in hours; gains in the target's unit per input unit."""

    inputs: tuple[str, ...]
    start: tuple[float, ...]           # g_1..g_m, g_0 from a static least-squares fit
    scale: float                       # the target's spread, for the noise starts

    name: ClassVar[str] = "first_order"

    @property
    def parameters(self) -> tuple:
        s = max(self.scale, 1e-6)
        gains = tuple(sto.Param(f"g_{c}", v, -1e6, 1e6, "", f"gain of {c}") for c, v in zip(self.inputs, self.start))
        return ((sto.Param("tau", 1.0, 1e-3, 1e4, "h", "time constant"),) + gains
                + (sto.Param("g_0", self.start[-1], -1e9, 1e9, "", "offset"),
                   sto.Param("sigma", 0.1 * s, 1e-6 * s, 1e3 * s, "/√h", "process noise"),
                   sto.Param("r", 0.05 * s, 1e-6 * s, 1e3 * s, "", "measurement noise")))

    def system(self, values) -> sto.System:
        tau = values["tau"]
        b = np.array([values[f"g_{c}"] for c in self.inputs] + [values["g_0"]]) / tau
        return sto.System(np.array([[[-1.0 / tau]]]), b[None, None, :], np.ones((1, 1)),
                          np.zeros((1, len(b))), np.array([values["sigma"]]), np.array([values["r"]]))


class GreyBox(ThermalModel):
    """A stochastic RC network per target, fitted by maximum likelihood (see the module docstring)."""

    extra_input_roles: ClassVar[tuple[str, ...]] = BUILDING_ROLES
    requires_roles: ClassVar[tuple[str, ...]] = ("ambient", "heating")   # AutoML: buildings only
    history_length: ClassVar[int | None] = None
    automl_cost: ClassVar[str] = "expensive"
    automl_features: ClassVar[bool] = False

    def __init__(self, structure: str = "select", starts: int = 2, maxiter: int = 300, random_state: int = 0):
        self.structure = structure
        self.starts = starts
        self.maxiter = maxiter  # search iterations per start of one fit (Ti, generic); the selection keeps its own
        self.random_state = random_state

    @classmethod
    def get_test_params(cls):
        return [{"structure": "Ti", "starts": 1, "maxiter": 90}]

    @classmethod
    def search_space(cls):
        return {"structure": {"type": "categorical", "choices": list(STRUCTURES)}}

    # ------------------------------------------------------------------------------------------------ fitting
    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        if self.structure not in STRUCTURES:
            raise ValueError(f"structure must be one of {STRUCTURES}, got {self.structure!r}")
        roles = X.attrs.get("roles", {})
        by_role = {r: [c for c in X.columns if roles.get(c) == r] for r in BUILDING_ROLES}
        self.building_ = len(by_role["ambient"]) == 1 and len(by_role["heating"]) == 1 \
            and len(by_role["solar_irradiance"]) <= 1
        t = _hours(X)
        self.systems_, self.structures_ = [], []
        for j in range(y.shape[1]):
            if self.building_:
                net = sto.load("building_ti")
                cols = {net.input_of(r): (by_role[r] or [None])[0] for r in BUILDING_ROLES}
                self.columns_ = [cols[c] for c in net.input_names]
                data = sto.Series.of(t, self._u(X), y[:, j:j + 1])
                if self.structure == "select":
                    est = forward_select(net, data, seed=self.random_state, starts=self.starts).selected.estimate
                else:
                    est = sto.fit(ti_start(net, data), data, seed=self.random_state, starts=self.starts,
                                  maxiter=self.maxiter, information=False)
                self.structures_.append(sto.structure_name(est.model))
            else:
                self.columns_ = list(X.columns)
                U = self._u(X)
                coef, *_ = np.linalg.lstsq(np.column_stack([U[:, :-1], np.ones(len(U))]), y[:, j], rcond=None)
                model = FirstOrder(tuple(self.columns_), tuple(float(c) for c in coef), float(np.std(y[:, j])))
                est = sto.fit(model, sto.Series.of(t, U, y[:, j:j + 1]), seed=self.random_state,
                              starts=self.starts, maxiter=self.maxiter, information=False)
                self.structures_.append(model.name)
            self.systems_.append(est.system)

    def _u(self, X: pd.DataFrame) -> np.ndarray:
        """Inputs in the networks' order (a missing solar channel reads 0; the generic network adds a 1)."""
        cols = [X[c].to_numpy(float) if c is not None else np.zeros(len(X)) for c in self.columns_]
        if not self.building_:
            cols.append(np.ones(len(X)))
        return np.column_stack(cols)

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        U, t = self._u(X), _hours(X)
        return np.column_stack([_simulate(s, U, t) for s in self.systems_])


def _hours(X: pd.DataFrame) -> np.ndarray:
    """Row times in hours (the index in s), or the row number × 15 min where the index is not numeric."""
    try:
        t = np.asarray(X.index, dtype=float)
    except (TypeError, ValueError):
        t = np.arange(len(X)) * 900.0
    return t / 3600.0


def _simulate(system: sto.System, U: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The SDE's mean output over the inputs ``U`` (held over each step) from the equilibrium of the first row's
    inputs."""
    x = system.steady_state(0, U[0])
    out = np.empty(len(U))
    steps: dict[float, tuple[np.ndarray, np.ndarray]] = {}
    for k in range(len(U)):
        out[k] = float(system.C[0] @ x + system.D[0] @ U[k])
        if k + 1 < len(U):
            dt = round(float(t[k + 1] - t[k]), 9)
            if dt not in steps:
                steps[dt] = system.discrete(0, dt)[:2] if dt > 0 and math.isfinite(dt) else (
                    np.eye(len(x)), np.zeros(system.B.shape[1:]))
            Phi, Gam = steps[dt]
            x = Phi @ x + Gam @ U[k]
    return out


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "greybox", GreyBox)
