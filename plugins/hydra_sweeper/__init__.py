"""Hydra sweeper plugin: ``hydra/sweeper=thermodrift`` tunes any Hydra app with thermodrift's Optuna samplers.

    python app.py -m hydra/sweeper=thermodrift hydra.sweeper.sampler=pso hydra.sweeper.n_trials=60 \
        +hydra.sweeper.sampler_params.population_size=12 'x=interval(-5, 5)' 'lr=tag(log, interval(1e-4, 1e-1))'

The search space is Hydra's override syntax, on the command line or under ``hydra.sweeper.params`` (see
``config.py``); the task function returns the objective. Every job that raises or returns a non-finite value
is a FAIL trial and the sweep goes on. With ``hydra.sweeper.storage=sqlite:///sweep.db`` a sweep that was
stopped resumes where it stopped: ``n_trials`` is the study's total budget.

Hydra finds this package by walking the ``hydra_plugins`` namespace package on disk. A regular install
(``pip install .``) and a strict editable install (``pip install -e . --config-settings editable_mode=strict``)
put it there. setuptools' default (lenient) editable install serves it through an import hook that the walk
cannot list, so there an app calls :func:`register` before ``@hydra.main`` runs. ``thermodrift run`` does it
through the same entry-point door as every other plugin: this module is an entry point of the ``thermodrift``
group whose ``thermodrift_hydra_plugins`` hook hands :func:`register` to the registry.
"""

from thermodrift.core.hookspecs import hookimpl


def register() -> None:
    """Add the sweeper class and its ``hydra/sweeper/thermodrift`` config to Hydra explicitly (idempotent)."""
    from hydra.core.plugins import Plugins

    from hydra_plugins.thermodrift_sweeper import config
    from hydra_plugins.thermodrift_sweeper.sweeper import ThermodriftSweeper

    config.store()
    Plugins.instance().register(ThermodriftSweeper)


@hookimpl
def thermodrift_hydra_plugins(registry):
    registry.add_hydra_plugin(register)
