"""Hydra sweeper plugin: ``hydra/sweeper=thermodrift`` tunes any Hydra app with thermodrift's Optuna samplers.

Hydra finds this package by walking the ``hydra_plugins`` namespace package on disk. A regular install
(``pip install .``) and a strict editable install (``pip install -e . --config-settings editable_mode=strict``)
put it there. setuptools' default (lenient) editable install serves it through an import hook that the walk
cannot list, so there an app calls :func:`register` before ``@hydra.main`` runs.
"""


def register() -> None:
    """Add the sweeper class and its ``hydra/sweeper/thermodrift`` config to Hydra explicitly (idempotent)."""
    from hydra.core.plugins import Plugins

    from hydra_plugins.thermodrift_sweeper import config  # noqa: F401  (importing it stores the config)
    from hydra_plugins.thermodrift_sweeper.sweeper import ThermodriftSweeper

    Plugins.instance().register(ThermodriftSweeper)
