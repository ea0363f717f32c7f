"""Physics benchmark: simulation speed, calibration of the auto baseline on FL_THERMAL, and held-out accuracy.

Prints one table:

* simulation — one 46 h run at 15 s of the 15-node reference network (median wall time, target ≤ 0.2 s), through
  the engine (``physics.simulate``) and through the calibration's modal propagator (``calibrate.trajectory``);
* calibration — wall time of ``calibrate`` with the ``auto`` network on the whole FL_THERMAL recording (target
  ≤ 60 s) and its per-channel RMSE (K, µm);
* held out — ch3 RMSE (µm) of ``lptn``, ``lptn_hybrid`` and ``mlr`` on "FL_THERMAL 5000 rpm held out" (train
  t < 24.13 h, test 24.13–32.13 h, all 16 temperatures; target: lptn_hybrid below mlr).

Run::

    python benchmarks/bench_physics.py [--data ../shared/data/fl_thermal] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from thermodrift.core import physics, registry
from thermodrift.core.physics import calibrate as cal
from thermodrift.core.physics import scenarios
from thermodrift.core.splits import TimeWindow

HERE = Path(__file__).resolve().parent
DEFAULT_DATA = HERE.parent.parent / "shared" / "data" / "fl_thermal"


def simulation_times(repeats: int) -> dict[str, float]:
    """Median wall time (s) of one FL_THERMAL-programme run of the 15-node reference network."""
    sys.path.insert(0, str(HERE))
    from bench_simulation import reference_network, time_simulation

    net, scen = reference_network(), scenarios.fl_thermal(dt_s=15.0)
    engine = time_simulation(net, scen, repeats=repeats)["median_s"]
    comp = physics.CompiledNetwork(net)
    times = []
    for _ in range(repeats + 1):
        start = time.perf_counter()
        cal.trajectory(physics.CompiledNetwork(net), scen)
        times.append(time.perf_counter() - start)
    ref = physics.simulate(comp, scen).temperatures.to_numpy()
    assert np.allclose(cal.trajectory(comp, scen), ref, atol=1e-8), "modal propagator disagrees with the engine"
    return {"nodes": len(net.nodes), "steps": len(scen), "engine_s": engine, "modal_s": statistics.median(times[1:])}


def held_out(recording) -> dict[str, float]:
    """ch3 RMSE (µm) on the FL_THERMAL 5000 rpm held-out protocol."""
    fold = TimeWindow(24.13, 24.13, 32.13).folds(recording)[0]
    temps = recording.columns("temperature")
    speed = recording.columns("speed")
    y = recording.data[["ch3(um)"]]
    out = {}
    for name in ("lptn", "lptn_hybrid", "mlr"):
        cols = temps + (speed if name.startswith("lptn") else [])
        X = recording.data[cols]
        start = time.perf_counter()
        model = registry.create("model", name).fit(X.iloc[fold.train], y.iloc[fold.train])
        pred = model.predict(X.iloc[fold.test])[:, 0]
        out[name] = float(np.sqrt(np.mean((y.iloc[fold.test].to_numpy()[:, 0] - pred) ** 2)))
        out[f"{name}_s"] = time.perf_counter() - start
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder of the FL_THERMAL workbook")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    recording = registry.create("dataset", "fl_thermal", path=str(args.data))

    sim = simulation_times(args.repeats)
    start = time.perf_counter()
    result = cal.calibrate(recording)
    cal_s = time.perf_counter() - start
    ho = held_out(recording)

    rows = [
        ("simulation, engine", f"{sim['nodes']} nodes, {sim['steps']} steps", f"{sim['engine_s']:.3f} s", "≤ 0.2 s"),
        ("simulation, modal", f"{sim['nodes']} nodes, {sim['steps']} steps", f"{sim['modal_s']:.3f} s", "≤ 0.2 s"),
        ("calibration, auto", f"{len(result.estimates)} parameters, {result.evaluations} simulations",
         f"{cal_s:.1f} s", "≤ 60 s"),
    ]
    for c, v in result.rmse.items():
        unit = "K" if result.channel_kind[c] == "temperature" else "µm"
        rows.append((f"  RMSE {c}", f"before {result.rmse_initial[c]:.3f} {unit}", f"{v:.3f} {unit}", ""))
    for name in ("lptn", "lptn_hybrid", "mlr"):
        target = "< mlr" if name == "lptn_hybrid" else ""
        rows.append((f"held out ch3, {name}", f"fit+predict {ho[name + '_s']:.1f} s", f"{ho[name]:.2f} µm", target))
    w = [max(len(r[i]) for r in rows) for i in range(4)]
    header = ("case", "detail", "measured", "target")
    print("  ".join(h.ljust(n) for h, n in zip(header, w)))
    for r in rows:
        print("  ".join(v.ljust(n) for v, n in zip(r, w)))
    top = result.unidentifiable
    if top:
        print(f"not identifiable: {', '.join(u['parameter'] for u in top)}")


if __name__ == "__main__":
    main()
