"""Red-billed blue magpie optimiser (Fu et al. 2024, Artif. Intell. Rev. 57:134, doi 10.1007/s10462-024-10716-3).

One iteration is two generations of N evaluations each (generation 0 is the random initial population):

* search for food (odd generations), Eqs. 3-4: with probability eps = 0.5
  X_i <- X_i + (mean(X_p) - X_R1) r over a small group p of 2..5 random magpies, else the same with a cluster q
  of 10..N random magpies (all N when N < 10); R1 is a random magpie, r ~ U(0,1) one number per magpie;
* attack prey (even generations), Eqs. 5-6: with probability eps X_i <- X_food + CF (mean(X_p) - X_i) * n, else
  with q; n ~ N(0,1)^D; CF = (1 - t/T)^(2t/T) with t the iteration and T = (n_trials - N) / (2N);
* food storage (Eq. 7) after both phases: a magpie keeps its old position if that was better (greedy).

X_food is the best position so far. Groups are drawn from the population of the last closed generation, so every
magpie of a phase moves from the same population X(t), as the equations say (the published MATLAB loop updates X in
place, so later magpies there see earlier magpies' unevaluated moves).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from thermodrift.core.hookspecs import hookimpl
from thermodrift.optimizers import Context, Member, Move, PopulationSampler, Population

EPSILON = 0.5  # probability of the small group p (Eqs. 3 and 5)


class RBMOSampler(PopulationSampler):
    """Red-billed blue magpie optimiser. Args: see :class:`PopulationSampler` (the paper uses N >= 10)."""

    prefix = "rbmo"
    generational = True

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"population_size": 4, "n_trials": 20}, {"population_size": 12, "n_trials": 60}]

    @staticmethod
    def phase_of(gen: int) -> str:
        """``init`` for generation 0, then ``search`` and ``attack`` alternating."""
        return "init" if gen == 0 else ("search" if gen % 2 else "attack")

    def iteration_ratio(self, gen: int) -> float:
        """t/T for the iteration that generation ``gen`` belongs to, capped at 1."""
        t = (gen + 1) // 2
        total = max(self.n_trials - self.population_size, 1) / (2 * self.population_size)
        return min(1.0, t / total)

    def _propose(self, ctx: Context) -> Move:
        if ctx.population is None:
            return Move(ctx.rng.random(ctx.dim), "init")
        phase = self.phase_of(ctx.gen)
        if phase == "search":
            return Move(self._search(ctx, ctx.population), phase)
        ratio = self.iteration_ratio(ctx.gen)
        return Move(self._attack(ctx, ctx.population, (1.0 - ratio) ** (2.0 * ratio)), phase)

    def _replaces(self, new: Member, old_fitness: float) -> bool:
        return new.fitness <= old_fitness  # Eq. 7, food storage

    def _group_mean(self, ctx: Context, pop: Population) -> np.ndarray:
        n = len(pop.fitness)
        if ctx.rng.random() < EPSILON:
            size = ctx.rng.integers(2, min(5, n) + 1)
        else:
            size = ctx.rng.integers(min(10, n), n + 1)
        return pop.x[ctx.rng.choice(n, size=size, replace=False)].mean(axis=0)

    def _search(self, ctx: Context, pop: Population) -> np.ndarray:
        mean = self._group_mean(ctx, pop)
        r1 = ctx.rng.integers(len(pop.fitness))
        return pop.x[ctx.slot] + (mean - pop.x[r1]) * ctx.rng.random()

    def _attack(self, ctx: Context, pop: Population, cf: float) -> np.ndarray:
        mean = self._group_mean(ctx, pop)
        return pop.best_x + cf * (mean - pop.x[ctx.slot]) * ctx.rng.standard_normal(ctx.dim)


@hookimpl
def thermodrift_register_optimizers(registry):
    registry.add("optimizer", "rbmo", RBMOSampler)
