"""Firefly algorithm (Yang 2008, 2009), synchronous: N evaluations per generation.

Library firefly variants evaluate after every pairwise move (N^2 evaluations per generation), which a deep
learning HPO cannot afford. Here firefly i composes its moves toward every firefly that was brighter in the last
closed generation, dimmest first so the brightest pulls last (as in Yang's sorted loop), each move
x_i <- x_i + beta0 exp(-gamma r_ij^2) (x_j - x_i) with r_ij measured from the moving x_i; then adds one random
step alpha_t (u - 1/2), u ~ U(0,1)^D, alpha_t = alpha0 theta^t, and is evaluated once. The brightest only walks.
The new generation replaces the old (no greedy selection, as in the original).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from thermodrift.core.hookspecs import hookimpl
from thermodrift.optimizers import Context, Move, PopulationSampler


class FASampler(PopulationSampler):
    """Firefly algorithm in the unit cube.

    Args:
        population_size: fireflies per generation.
        beta0: attractiveness at distance 0.
        gamma: light absorption (1 suits the unit cube: attraction falls to 1/e at distance 1).
        alpha0, theta: random step at generation 0 and its decay per generation.
        n_trials, seed: see :class:`PopulationSampler`.
    """

    prefix = "fa"
    generational = True

    def __init__(self, *, population_size: int = 10, beta0: float = 1.0, gamma: float = 1.0, alpha0: float = 0.2,
                 theta: float = 0.97, n_trials: int = 100, seed: int | None = None) -> None:
        super().__init__(population_size=population_size, n_trials=n_trials, seed=seed)
        self.beta0, self.gamma, self.alpha0, self.theta = beta0, gamma, alpha0, theta

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"population_size": 4, "n_trials": 20}, {"population_size": 3, "gamma": 0.5, "theta": 0.9}]

    def _propose(self, ctx: Context) -> Move:
        pop = ctx.population
        if pop is None:
            return Move(ctx.rng.random(ctx.dim), "init")
        i = ctx.slot
        x = pop.x[i].copy()
        order = sorted(range(len(pop.fitness)), key=lambda j: (-pop.fitness[j], j))
        for j in order:
            if pop.fitness[j] < pop.fitness[i]:
                r2 = float(np.sum((x - pop.x[j]) ** 2))
                x += self.beta0 * np.exp(-self.gamma * r2) * (pop.x[j] - x)
        alpha = self.alpha0 * self.theta ** ctx.gen
        return Move(x + alpha * (ctx.rng.random(ctx.dim) - 0.5), "move")


@hookimpl
def thermodrift_register_optimizers(registry):
    registry.add("optimizer", "fa", FASampler)
