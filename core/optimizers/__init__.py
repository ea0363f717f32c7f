"""The public base for population metaheuristics as Optuna samplers (``thermodrift.optimizers``).

A new metaheuristic subclasses :class:`PopulationSampler`, sets ``prefix`` and ``generational`` and implements
``_propose(ctx) -> Move``; the base keeps the whole population state in Optuna storage (see
:mod:`thermodrift.optimizers.population`). ``docs/templates/optimizer_plugin.py`` is a complete one-file example.
"""

from thermodrift.optimizers.population import Context, Member, Move, Population, PopulationSampler

__all__ = ["Context", "Member", "Move", "Population", "PopulationSampler"]
