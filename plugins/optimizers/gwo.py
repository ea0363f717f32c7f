"""Grey wolf optimiser (Mirjalili, Mirjalili & Lewis 2014) as an asynchronous Optuna sampler.

alpha, beta, delta are the three best trials so far. A wolf moves when its own result is in, from its latest
position X: for each leader L and dimension, A = 2a r1 - a, C = 2 r2, D_L = |C X_L - X|, X_L' = X_L - A D_L;
then X <- (X_alpha' + X_beta' + X_delta') / 3, clipped to the unit cube. a falls linearly from 2 to 0 over the
budget (exploration while |A| > 1, exploitation after).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from thermodrift.core.hookspecs import hookimpl
from thermodrift.optimizers import Context, Move, PopulationSampler


class GWOSampler(PopulationSampler):
    """Grey wolf optimiser. Args: see :class:`PopulationSampler` (``population_size`` is the pack size)."""

    prefix = "gwo"

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"population_size": 4, "n_trials": 20}, {"population_size": 6, "n_trials": 50}]

    def _propose(self, ctx: Context) -> Move:
        leaders = list(ctx.ranked[:3])
        if ctx.latest is None or not leaders:
            return Move(ctx.rng.random(ctx.dim), "init")
        leaders += leaders[-1:] * (3 - len(leaders))  # fewer than three finished trials: the best repeat
        x = ctx.latest.x
        a = 2.0 * (1.0 - ctx.progress)
        moved = []
        for leader in leaders:
            big_a = 2.0 * a * ctx.rng.random(ctx.dim) - a
            big_c = 2.0 * ctx.rng.random(ctx.dim)
            moved.append(leader.x - big_a * np.abs(big_c * leader.x - x))
        return Move(np.clip(np.mean(moved, axis=0), 0.0, 1.0), "move")


@hookimpl
def thermodrift_register_optimizers(registry):
    registry.add("optimizer", "gwo", GWOSampler)
