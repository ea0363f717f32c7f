"""Sampler overhead per ask once a study holds a given number of finished trials: the overhead part of
``bench_samplers.py`` on its own, for quick checks while working on a sampler.

Each sampler fills an in-memory study on a 5-D sphere by itself, then ``ask`` + suggestions + ``tell`` is timed
(median CPU ms, wall ms in brackets). Random search is Optuna's own floor.

    python benchmarks/bench_sampler_overhead.py                       # population samplers + random
    python benchmarks/bench_sampler_overhead.py --samplers pso tpe --at 100 1000
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_samplers import OURS, overhead_run  # noqa: E402  (the one implementation of the measurement)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samplers", nargs="+", default=["random", "pso_constriction", *OURS])
    parser.add_argument("--at", nargs="+", type=int, default=[100, 1000], help="finished trials before timing")
    args = parser.parse_args(argv)
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    sizes = tuple(sorted(args.at))
    print("sampler overhead per ask: CPU ms (wall ms), median; D = 5, in-memory storage")
    print(f"{'sampler':18s}" + "".join(f"{f'{n} trials':>18s}" for n in sizes))
    for name in args.samplers:
        ms = overhead_run(name, sizes)["ms"]
        print(f"{name:18s}" + "".join(f"{f'{ms[n][0]:.2f} ({ms[n][1]:.2f})':>18s}" for n in sizes), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
