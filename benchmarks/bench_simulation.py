"""Simulation speed of the thermal network engine: median wall time of one full simulation.

The reference case is 46 h at 15 s (the FL_THERMAL programme, 11,114 steps) on a 15-node network (the
motorized spindle of study S3 plus a slow structural mode and a screw node). Run::

    python benchmarks/bench_simulation.py [--repeats 7]

:func:`time_simulation` is importable for other benchmarks (calibration re-simulates the same way).
"""

from __future__ import annotations

import argparse
import statistics
import time

from thermodrift.core import physics
from thermodrift.core.physics import scenarios


def time_simulation(network: physics.Network, scenario: physics.Scenario, *, repeats: int = 7,
                    method: str = "exact") -> dict:
    """Median and best wall time (s) of ``physics.simulate`` over ``repeats`` runs (after one warm-up)."""
    physics.simulate(network, scenario, method=method)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        physics.simulate(network, scenario, method=method)
        times.append(time.perf_counter() - start)
    return {"network": network.name, "nodes": len(network.nodes), "scenario": scenario.name,
            "steps": len(scenario), "method": method, "median_s": statistics.median(times), "best_s": min(times)}


def reference_network() -> physics.Network:
    """The 15-node benchmark network."""
    from thermodrift.core import registry

    net = physics.load_network("motorized_spindle_s3")
    net = registry.create("mechanism", "slow_structural_mode", nodes=["flange"]).apply(net)
    return registry.create("mechanism", "axis_drive_heat").apply(net)


def cases() -> list[tuple[physics.Network, physics.Scenario, str]]:
    fl = scenarios.fl_thermal(dt_s=15.0)
    ref = reference_network()
    return [(ref, fl, "exact"), (ref, fl, "backward_euler"),
            *[(physics.load_network(n), fl, "exact") for n in ("demo_spindle", "turning_centre_s1", "vmc_spindle_s2")],
            (ref, scenarios.s2_warmup(dt_s=1.0), "exact")]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    print(f"{'network':<22} {'nodes':>5} {'scenario':<12} {'steps':>6} {'method':<15} {'median ms':>10} {'best ms':>8}")
    for net, scen, method in cases():
        r = time_simulation(net, scen, repeats=args.repeats, method=method)
        print(f"{r['network']:<22} {r['nodes']:>5} {r['scenario']:<12} {r['steps']:>6} {r['method']:<15} "
              f"{r['median_s'] * 1e3:>10.1f} {r['best_s'] * 1e3:>8.1f}")


if __name__ == "__main__":
    main()
