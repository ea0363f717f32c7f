"""A Hydra app that knows nothing of thermodrift: a quadratic with its minimum 0 at x=1.5, y=-0.5, n=3,
act=tanh, lr=0.01. The sweeper tests run it as ``python quadratic.py -m hydra/sweeper=thermodrift ...``."""

import math

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def main(cfg: DictConfig) -> float | tuple[float, float]:
    if cfg.interrupt_on_job is not None and HydraConfig.get().job.num == cfg.interrupt_on_job:
        raise KeyboardInterrupt  # as if the user pressed Ctrl-C during this job
    if cfg.mode == "raise":
        raise RuntimeError("this job fails on purpose")
    if cfg.mode == "non_finite":
        return math.nan
    assert isinstance(cfg.n, int) and isinstance(cfg.act, str) and isinstance(cfg.lr, float)
    value = ((cfg.x - 1.5) ** 2 + (cfg.y + 0.5) ** 2 + 0.1 * (cfg.n - 3) ** 2
             + (cfg.act != "tanh") + (math.log10(cfg.lr) + 2.0) ** 2)
    if cfg.objectives == 2:
        return value, (cfg.x + 1.0) ** 2
    return value


def relu_learning_rate(cfg: DictConfig, trial) -> None:
    """A custom search space (``hydra.sweeper.custom_search_space``): lr is tuned only for act=relu."""
    if trial.params.get("act") == "relu":
        trial.suggest_float("lr", 1e-3, 1e-1, log=True)


if __name__ == "__main__":
    main()
