"""Template: a new metaheuristic as a thermodrift optimizer plugin (an Optuna sampler) in one file.

How to use:
1. Copy this file into your package, e.g. ``my_samplers/jaya.py``, and rename class, prefix and registry name.
2. Fill in the ``todo`` parts. Subclass :class:`thermodrift.optimizers.PopulationSampler` and write only the
   algorithm's move, ``_propose(ctx) -> Move``: a position in the unit cube [0, 1]^D (D = the encoded search
   space) for the trial in slot ``ctx.slot``. The base does the rest: encoding every parameter kind (log,
   step, int, categorical), keeping the population in the study's storage (so threads, processes and a
   resumed run share it), slots and generations, failed and pruned trials (worst fitness), enqueued trials
   (adopted into the population), seeding (``ctx.rng`` is per trial), and parameters outside the common
   search space. An algorithm that moves the whole population once per generation sets ``generational =
   True``, reads ``ctx.population`` and may override ``_replaces(new, old_fitness)`` (greedy selection).
3. One entry-point line in your ``pyproject.toml``::

       [project.entry-points.thermodrift]
       jaya = "my_samplers.jaya"

4. ``thermodrift run optimizer=jaya`` works with no YAML: its config is built from the registry
   (``params`` = the constructor's defaults). For other defaults ship ``my_samplers/conf/optimizer/jaya.yaml``
   and add ``registry.add_searchpath("pkg://my_samplers.conf")`` in a ``thermodrift_hydra_searchpaths`` hook.
5. Check it: ``from thermodrift.testing import check_component; check_component("optimizer", "jaya")``
   or subclass ``thermodrift.testing.pytest_components.OptimizerTests`` with ``name = "jaya"``; Optuna's own
   sampler suite runs on it as in thermodrift's ``tests/test_samplers_conformance.py``.

The example is Jaya (Rao 2016), parameter-free: each member moves towards the best and away from the worst
member, X' = X + r1 (X_best - |X|) - r2 (X_worst - |X|), r1, r2 uniform per dimension.
"""

from typing import Any

import numpy as np

from thermodrift.core.hookspecs import hookimpl
from thermodrift.optimizers import Context, Move, PopulationSampler


# todo: rename the class, say what the algorithm does; constructor: the base's population_size, n_trials
# and seed (keyword-only), plus your own settings, each stored unchanged under its own name
class JayaSampler(PopulationSampler):
    """Jaya: every member moves towards the best and away from the worst finished member."""

    prefix = "jaya"  # todo: the namespace of this algorithm's trial attributes in the storage

    # todo: at least two cheap settings for the conformance suite (small populations, small budgets)
    @classmethod
    def get_test_params(cls) -> list[dict[str, Any]]:
        return [{"population_size": 4, "n_trials": 20}, {"population_size": 6, "n_trials": 50}]

    # todo: the move; ctx.latest is this slot's latest trial (None before its first), ctx.ranked every finished
    # member with finite fitness, best first; draw every random number from ctx.rng
    def _propose(self, ctx: Context) -> Move:
        if ctx.latest is None or not ctx.ranked:
            return Move(ctx.rng.random(ctx.dim), "init")
        x, best, worst = ctx.latest.x, ctx.ranked[0].x, ctx.ranked[-1].x
        step = ctx.rng.random(ctx.dim) * (best - np.abs(x)) - ctx.rng.random(ctx.dim) * (worst - np.abs(x))
        return Move(np.clip(x + step, 0.0, 1.0), "move")


# todo: the registry name users type in `thermodrift run optimizer=<name>`
@hookimpl
def thermodrift_register_optimizers(registry):
    registry.add("optimizer", "jaya", JayaSampler)
