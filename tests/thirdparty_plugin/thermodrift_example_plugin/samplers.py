"""Optimizer ``sobol_demo``: a scrambled quasi-random (Sobol or Halton) design, Optuna's ``QMCSampler``."""

import warnings

import optuna

from thermodrift.core.hookspecs import hookimpl


def sobol_demo(seed: int | None = None, qmc_type: str = "sobol"):
    """A space-filling design over the search space; ``qmc_type`` is ``"sobol"`` or ``"halton"``."""
    with warnings.catch_warnings():  # Optuna marks QMCSampler experimental
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        return optuna.samplers.QMCSampler(qmc_type=qmc_type, scramble=True, seed=seed)


sobol_demo.get_test_params = lambda: [{"qmc_type": "sobol"}, {"qmc_type": "halton"}]


@hookimpl
def thermodrift_register_optimizers(registry):
    registry.add("optimizer", "sobol_demo", sobol_demo)
