"""Particle swarm optimisation (Kennedy & Eberhart 1995) as an asynchronous Optuna sampler.

Each particle moves when its own result is in, from its latest position and velocity, toward its personal best
and the swarm's best so far (all in the unit cube, see ``_population``). Two forms:

* inertia: v <- w v + c1 r1 (p - x) + c2 r2 (g - x), w linear from ``w_start`` to ``w_end`` over the budget;
* constriction (Clerc & Kennedy 2002): v <- chi [v + c1 r1 (p - x) + c2 r2 (g - x)],
  chi = 2 / |2 - phi - sqrt(phi^2 - 4 phi)|, phi = c1 + c2 > 4 (2.05 + 2.05 gives chi = 0.7298, the same swarm
  as w = 0.7298, c = 1.4962).

Then |v_d| <= ``v_max`` and x <- x + v. At a bound, ``boundary="clip"`` stops the particle there and zeroes that
velocity component; ``"reflect"`` mirrors the position back inside and reverses that component. Velocities start
at zero (Engelbrecht 2012: random initial velocities mostly make particles leave the box).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from thermodrift.core.hookspecs import hookimpl
from thermodrift.optimizers import Context, Move, PopulationSampler


class PSOSampler(PopulationSampler):
    """Particle swarm optimisation.

    Args:
        population_size: swarm size.
        form: ``"inertia"`` or ``"constriction"``.
        w_start, w_end: inertia weight at the start and end of the budget (inertia form only).
        c1, c2: cognitive and social coefficients; default 2.0 (inertia) or 2.05 (constriction).
        v_max: velocity clamp per dimension in the unit cube (``None``: no clamp).
        boundary: ``"clip"`` or ``"reflect"``.
        n_trials, seed: see :class:`PopulationSampler`.
    """

    prefix = "pso"

    def __init__(self, *, population_size: int = 10, form: str = "inertia", w_start: float = 0.9,
                 w_end: float = 0.4, c1: float | None = None, c2: float | None = None, v_max: float | None = 0.2,
                 boundary: str = "clip", n_trials: int = 100, seed: int | None = None) -> None:
        super().__init__(population_size=population_size, n_trials=n_trials, seed=seed)
        if form not in ("inertia", "constriction"):
            raise ValueError(f"form must be 'inertia' or 'constriction', got {form!r}")
        if boundary not in ("clip", "reflect"):
            raise ValueError(f"boundary must be 'clip' or 'reflect', got {boundary!r}")
        default_c = 2.0 if form == "inertia" else 2.05
        self.form, self.w_start, self.w_end, self.v_max, self.boundary = form, w_start, w_end, v_max, boundary
        self.c1 = default_c if c1 is None else float(c1)
        self.c2 = default_c if c2 is None else float(c2)
        if form == "constriction":
            phi = self.c1 + self.c2
            if phi <= 4:
                raise ValueError(f"constriction needs c1 + c2 > 4, got {phi}")
            self.chi = 2.0 / abs(2.0 - phi - math.sqrt(phi * phi - 4.0 * phi))

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"population_size": 4, "n_trials": 20},
                {"population_size": 3, "form": "constriction", "boundary": "reflect", "n_trials": 20}]

    def _propose(self, ctx: Context) -> Move:
        latest = ctx.latest
        if latest is None:
            return Move(ctx.rng.random(ctx.dim), "init", np.zeros(ctx.dim))
        x, v = latest.x, latest.v if latest.v is not None else np.zeros(ctx.dim)
        p = (ctx.own_best or latest).x
        g = (ctx.ranked[0] if ctx.ranked else latest).x
        r1, r2 = ctx.rng.random(ctx.dim), ctx.rng.random(ctx.dim)
        pull = self.c1 * r1 * (p - x) + self.c2 * r2 * (g - x)
        if self.form == "inertia":
            w = self.w_start + (self.w_end - self.w_start) * ctx.progress
            v = w * v + pull
        else:
            v = self.chi * (v + pull)
        if self.v_max is not None:
            v = np.clip(v, -self.v_max, self.v_max)
        x = x + v
        out = (x < 0) | (x > 1)
        if self.boundary == "clip":
            x, v = np.clip(x, 0, 1), np.where(out, 0.0, v)
        else:
            x = np.where(x < 0, -x, np.where(x > 1, 2 - x, x))
            x, v = np.clip(x, 0, 1), np.where(out, -v, v)
        return Move(x, "move", v)


class ConstrictionPSOSampler(PSOSampler):
    """:class:`PSOSampler` in the constriction form (c1 = c2 = 2.05, chi = 0.7298) unless ``form`` is given."""

    def __init__(self, **params: Any) -> None:
        params.setdefault("form", "constriction")
        super().__init__(**params)

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"population_size": 4, "n_trials": 20}]


@hookimpl
def thermodrift_register_optimizers(registry):
    registry.add("optimizer", "pso", PSOSampler)
    registry.add("optimizer", "pso_constriction", ConstrictionPSOSampler)
