"""Sampler overhead per ask at a given number of finished trials (in-memory storage, 5 float parameters).

For each sampler, a study is filled with finished trials of a cheap sphere objective; then each of the next
``--repeats`` trials is timed from ``study.ask()`` through the ``suggest_*`` calls (where the sampler runs) and
told its value. Prints a table of the median ms per ask. Random search is Optuna's own floor.

    python benchmarks/bench_sampler_overhead.py                        # population samplers + random
    python benchmarks/bench_sampler_overhead.py --samplers pso tpe --at 100 1000
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import optuna

from thermodrift.core import registry

DEFAULT = ["random", "pso", "pso_constriction", "gwo", "fa", "rbmo", "rbmox"]


def overhead_ms(name: str, finished: list[int], dim: int, repeats: int, seed: int) -> list[float]:
    """Median ms per ask after each count in ``finished`` (ascending) for sampler ``name``."""
    centre = np.linspace(-0.5, 0.5, dim)

    def suggest(trial: optuna.Trial) -> np.ndarray:
        return np.array([trial.suggest_float(f"x{i}", -1.0, 1.0) for i in range(dim)])

    factory = registry.get("optimizer", name).factory
    budget = max(finished) + repeats
    params = {"n_trials": budget} if registry._accepts(factory, "n_trials") else {}
    study = optuna.create_study(sampler=registry.create("optimizer", name, seed=seed, **params))
    out = []
    for target in finished:
        study.optimize(lambda t: float(np.sum((suggest(t) - centre) ** 2)), n_trials=target - len(study.trials))
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            trial = study.ask()
            x = suggest(trial)
            times.append(time.perf_counter() - start)
            study.tell(trial, float(np.sum((x - centre) ** 2)))
        out.append(1e3 * float(np.median(times)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samplers", nargs="+", default=DEFAULT)
    parser.add_argument("--at", nargs="+", type=int, default=[100, 1000], help="finished trials before timing")
    parser.add_argument("--dim", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    at = sorted(args.at)
    print(f"sampler overhead per ask, ms (median of {args.repeats}; D = {args.dim}, in-memory storage)")
    print(f"{'sampler':18s}" + "".join(f"{f'{n} trials':>14s}" for n in at))
    for name in args.samplers:
        ms = overhead_ms(name, at, args.dim, args.repeats, args.seed)
        print(f"{name:18s}" + "".join(f"{m:14.2f}" for m in ms), flush=True)


if __name__ == "__main__":
    main()
