"""Runtime ``transfer_function``: first-order-filtered temperatures and drive heat terms, linear read-out.

Per row: temperatures T (°C) and drive terms d = (|v| / v_ref)^p (speed rpm, cutting power W) feed first-order
filters x ← a·x + (1 − a)·u, a = exp(−Δt / τ) at the training sampling interval; the output (µm) is
W · [T, d, x] + c. Filters start at the first row's temperatures and at rest for drive terms, as
``plugins/models/transfer_function.py`` fits them.
"""

from __future__ import annotations

import numpy as np

from thermodrift.compensator.runtime import Base


class Runtime(Base):
    """State: ``temperature_columns``, ``drive_columns``, ``drive_ref``, ``powers``, ``decay`` (per τ),
    ``weights`` (targets × features), ``intercept`` (targets)."""

    def __init__(self, state):
        super().__init__(state)
        pos = {c: i for i, c in enumerate(self.inputs)}
        self.t_idx = np.array([pos[c] for c in state["temperature_columns"]], dtype=int)
        self.d_idx = np.array([pos[c] for c in state["drive_columns"]], dtype=int)
        self.ref = np.asarray(state["drive_ref"], dtype=float).reshape(-1)
        self.powers = np.asarray(state["powers"], dtype=float).reshape(-1)
        decay = np.asarray(state["decay"], dtype=float).reshape(-1)
        self.n_taus = len(decay)
        n_t, n_terms = len(self.t_idx), len(self.d_idx) * len(self.powers)
        self.a = np.concatenate([np.repeat(decay, n_t), np.repeat(decay, n_terms)])
        self.b = 1.0 - self.a
        W = np.atleast_2d(np.asarray(state["weights"], dtype=float))
        self.w_temp, self.w_terms = W[:, :n_t].T.copy(), W[:, n_t:n_t + n_terms].T.copy()
        self.w_state = W[:, n_t + n_terms:].T.copy()
        self.c = np.asarray(state["intercept"], dtype=float).reshape(-1)
        self.n_terms = n_terms

    def streamer(self, history=None, times_s=None) -> "Streamer":
        return self.warm(Streamer(self), history, times_s)


class Streamer:
    def __init__(self, rt: Runtime):
        self.rt = rt
        self.state: np.ndarray | None = None

    def update(self, values: np.ndarray, t_s: float | None = None) -> np.ndarray:
        rt = self.rt
        temps = values[rt.t_idx]
        if len(rt.d_idx):
            terms = np.power.outer(np.abs(values[rt.d_idx]) / rt.ref, rt.powers).T.ravel()  # power-major
        else:
            terms = np.zeros(0)
        if self.state is None:
            self.state = np.concatenate([np.tile(temps, rt.n_taus), np.zeros(rt.n_terms * rt.n_taus)])
        u = np.concatenate([np.tile(temps, rt.n_taus), np.tile(terms, rt.n_taus)])
        self.state = rt.a * self.state + rt.b * u
        return temps @ rt.w_temp + terms @ rt.w_terms + self.state @ rt.w_state + rt.c
