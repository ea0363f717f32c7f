"""RBMO-X: RBMO with the stabilisers of deep-learning training carried into the metaheuristic loop.

The seed study names an "enhanced RBMO" with SGDR warm restarts and gradient-norm clipping but gives no equations;
this is our design, every part switchable for ablation (all five off reproduces :class:`RBMOSampler` exactly,
same seed, same trials):

* ``step_clip`` -- step-norm clipping, the analogue of gradient clipping: a search or attack move of magpie i is
  shortened to ||x_new - X_i|| <= kappa sqrt(D) (sqrt(D) is the diagonal of the unit cube);
* ``cosine_cf`` -- the attack coefficient CF follows a cosine with warm restarts over iterations, the SGDR
  schedule: CF = (1 + cos(pi k / L)) / 2 with k the iterations since the last restart and L the cycle length
  (``cycle_iters``, multiplied by ``cycle_mult`` after each cycle end), replacing (1 - t/T)^(2t/T);
* ``restarts`` -- at a cycle end, or after ``patience`` iterations without a better X_food, the search phase of
  the next iteration re-diversifies the worst ``restart_fraction`` of the magpies with opposition points
  x -> 1 - x of their own positions (failed ones included), which replace them whatever their fitness (a
  stagnation restart also restarts the CF cycle);
* ``local_search`` -- the generations in the last ``local_fraction`` of the budget (at least the last one) sample
  X_food + sigma n, n ~ N(0,1)^D, sigma shrinking linearly from ``local_sigma`` to a tenth of it over those
  generations, kept greedily; it starts only after one whole search-attack iteration;
* ``recover`` -- the sampler-side divergence guard, the analogue of a trainer going back to its last good
  checkpoint: a magpie whose stored position has no finite fitness (its trial failed, e.g. its training diverged,
  or was pruned) is put back at X_food before the moves are drawn, so neither it nor the group means and random
  magpies R1 of the other moves start from a point known to fail;
* ``bounce_back`` -- a coordinate that a move takes out of the unit cube lands halfway between where the move
  started (the magpie, or X_food for the local search) and the bound it crossed (the midpoint-target repair),
  instead of on the bound as RBMO's clipping puts it. Clipping piles positions up on the range limits (structural
  bias: on the benchmark's ``bp`` task a fifth of RBMO's moves after generation 0 end exactly on a limit), and the
  limits of a training range are where training is least stable (the largest learning rate, the strongest
  weight decay).

Restart and cycle decisions are replayed from the stored best-fitness history, so they survive a resume.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from thermodrift.core.hookspecs import hookimpl
from thermodrift.optimizers import Context, Member, Move, Population
from thermodrift.plugins.optimizers.rbmo import RBMOSampler


class RBMOXSampler(RBMOSampler):
    """RBMO with step clipping, cosine warm-restart CF, opposition restarts and a final local search.

    Args:
        population_size, n_trials, seed: see :class:`PopulationSampler`.
        step_clip, kappa: step-norm clipping and its bound as a share of the cube diagonal.
        cosine_cf, cycle_iters, cycle_mult: cosine CF, first cycle length in iterations (``None``: a third of the
            iterations the budget allows, at least 2) and the cycle growth factor.
        restarts, patience, restart_fraction: opposition restarts, stagnation patience in iterations and the
            share of the population re-diversified.
        local_search, local_fraction, local_sigma: final local search, its share of the budget and its initial
            step in the unit cube.
        recover: magpies whose position failed or was pruned move from X_food.
        bounce_back: moves leaving the unit cube stop halfway to the bound instead of on it.
    """

    prefix = "rbmox"

    def __init__(self, *, population_size: int = 10, n_trials: int = 100, seed: int | None = None,
                 step_clip: bool = True, kappa: float = 0.3,
                 cosine_cf: bool = True, cycle_iters: int | None = None, cycle_mult: float = 1.0,
                 restarts: bool = True, patience: int = 3, restart_fraction: float = 0.3,
                 local_search: bool = True, local_fraction: float = 0.15, local_sigma: float = 0.05,
                 recover: bool = True, bounce_back: bool = True) -> None:
        super().__init__(population_size=population_size, n_trials=n_trials, seed=seed)
        self.step_clip, self.kappa = step_clip, kappa
        self.cosine_cf, self.cycle_mult = cosine_cf, cycle_mult
        iterations = max(n_trials - population_size, 1) / (2 * population_size)
        self.cycle_iters = max(2, round(iterations / 3)) if cycle_iters is None else int(cycle_iters)
        self.restarts, self.patience, self.restart_fraction = restarts, patience, restart_fraction
        self.local_search, self.local_fraction, self.local_sigma = local_search, local_fraction, local_sigma
        self.recover, self.bounce_back = recover, bounce_back
        # Generations 0..G-1 fill the budget; the last round(local_fraction G) of them (at least one) search locally
        # when generations 1 and 2 (one whole iteration) come before them.
        generations = -(-n_trials // population_size)
        first_local = generations - max(1, round(local_fraction * generations))
        self._first_local = first_local if local_search and first_local >= 3 else None
        self._local_generations = generations - first_local

    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"population_size": 4, "n_trials": 20},
                {"population_size": 4, "n_trials": 40, "cycle_iters": 2, "patience": 1, "local_fraction": 0.3,
                 "recover": False, "bounce_back": False}]

    def _propose(self, ctx: Context) -> Move:
        pop = ctx.population
        if pop is None:
            return Move(ctx.rng.random(ctx.dim), "init")
        if self.recover and np.isfinite(pop.best_fitness):
            failed = ~np.isfinite(pop.fitness)
            if failed.any():
                x = pop.x.copy()
                x[failed] = pop.best_x
                pop = Population(x, pop.fitness, pop.best_x, pop.best_fitness, pop.best_history)
        if self._first_local is not None and ctx.gen >= self._first_local:
            share = (ctx.gen - self._first_local) / max(1, self._local_generations - 1)  # 0 .. 1 over the phase
            sigma = self.local_sigma * (1.0 - 0.9 * min(1.0, share))
            return Move(self._repair(pop.best_x + sigma * ctx.rng.standard_normal(ctx.dim), pop.best_x), "local")
        phase = self.phase_of(ctx.gen)
        restart, cf = self._schedule(pop, ctx.gen)
        start = pop.x[ctx.slot]
        if phase == "search":
            if restart and ctx.slot in self._worst(pop):  # the opposite of its own position, not of X_food
                return Move(1.0 - ctx.population.x[ctx.slot], "restart")
            x = self._search(ctx, pop)
        else:
            x = self._attack(ctx, pop, cf)
        if self.step_clip:
            step = x - start
            limit = self.kappa * math.sqrt(ctx.dim)
            norm = float(np.linalg.norm(step))
            if norm > limit:
                x = start + step * (limit / norm)
        return Move(self._repair(x, start), phase)

    def _repair(self, x: np.ndarray, origin: np.ndarray) -> np.ndarray:
        """``x`` with every coordinate outside [0, 1] moved halfway from ``origin`` (inside) to the bound crossed."""
        if not self.bounce_back:
            return x
        return np.where(x > 1.0, 0.5 * (origin + 1.0), np.where(x < 0.0, 0.5 * origin, x))

    def _replaces(self, new: Member, old_fitness: float) -> bool:
        return new.phase == "restart" or new.fitness <= old_fitness

    def _worst(self, pop: Population) -> set[int]:
        n = len(pop.fitness)
        order = sorted(range(n), key=lambda i: (-pop.fitness[i], i))
        return set(order[:max(1, round(self.restart_fraction * n))])

    def _schedule(self, pop: Population, gen: int) -> tuple[bool, float]:
        """(restart in this iteration's search phase, CF of this iteration's attack phase), replayed from the
        best fitness after each closed generation (iteration k ends with generation 2k)."""
        t = (gen + 1) // 2
        history = pop.best_history
        start, length, stagnant, restart = 1, float(self.cycle_iters), 0, False
        for k in range(2, t + 1):
            stagnant = 0 if history[2 * k - 2] < history[2 * k - 4] else stagnant + 1
            cycle_end = self.cosine_cf and k - start >= length
            restart = cycle_end or (self.restarts and stagnant >= self.patience)
            if restart:
                start, stagnant = k, 0
                if cycle_end:
                    length *= self.cycle_mult
            restart = restart and self.restarts
        if self.cosine_cf:
            return restart, 0.5 * (1.0 + math.cos(math.pi * (t - start) / length))
        ratio = self.iteration_ratio(gen)
        return restart, (1.0 - ratio) ** (2.0 * ratio)


@hookimpl
def thermodrift_register_optimizers(registry):
    registry.add("optimizer", "rbmox", RBMOXSampler)
