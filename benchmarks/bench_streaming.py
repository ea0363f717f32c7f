"""Streaming latency of every registered model: ``streamer(history).update(row)``, as a CNC controller calls a
compensation model, next to the generic streamer (``components.Streamer``: a prediction over the kept rows per
update) and the gap between streamed and batch predictions.

Each model is built with its constructor defaults (torch models: the architecture at its default size, trained for
``--epochs`` epochs only, since latency does not depend on the weights; a model whose defaults cannot be fitted,
such as an ensemble without members, with its first conformance parameter set, marked "test params"), fitted on
the first 70 % of the recording's rows, and streamed over the next ``--rows`` rows after the training rows as
history. ms per update is the median over ``--repeats`` passes (one torch thread), wall and CPU time (a busy
machine stretches the wall time, not the CPU time); the two streamers run side by side, and the speed-up is the
ratio of their CPU times.
"max |stream - batch|" is the largest difference (µm) from ``predict(rows, history)`` (the contract: at most
1e-4 µm).

    python benchmarks/bench_streaming.py                         # every model on the tiny recording
    python benchmarks/bench_streaming.py --dataset motorized_spindle_s3 --models lstm dltk --epochs 2
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np


def per_update_ms(make, rows: list, repeats: int) -> tuple[float, float]:
    """Median wall and CPU ms per ``update`` of a fresh streamer from ``make()`` over ``rows`` (on a busy machine
    the wall time stretches; the CPU time is what the process itself needed)."""
    wall, cpu = [], []
    for _ in range(repeats):
        streamer = make()
        start, start_cpu = time.perf_counter(), time.process_time()
        for row in rows:
            streamer.update(row)
        cpu.append((time.process_time() - start_cpu) * 1e3 / len(rows))
        wall.append((time.perf_counter() - start) * 1e3 / len(rows))
    return statistics.median(wall), statistics.median(cpu)


def measure(name: str, rec, epochs: int, n_rows: int, repeats: int) -> dict:
    from thermodrift.core import registry
    from thermodrift.core.components import Streamer
    from thermodrift.core.study import INPUT_ROLES, model_inputs

    factory = registry.get("model", name).factory
    sensors = [c for role in INPUT_ROLES for c in rec.columns(role)]
    targets = rec.columns("displacement")
    X = model_inputs(rec, sensors, factory, targets)
    cut = int(0.7 * len(X))
    params = {"trainer__epochs": epochs, "trainer__t0": 1} if registry.accepts(factory, "trainer") else {}
    try:
        model = registry.create("model", name, **params).fit(X.iloc[:cut], rec.data[targets].iloc[:cut])
        sized = "defaults"
    except ValueError:  # a model that needs parameters (an ensemble needs members): its conformance parameters
        model = registry.create("model", name, **factory.get_test_params()[0])
        model.fit(X.iloc[:cut], rec.data[targets].iloc[:cut])
        sized = "test params"
    history, part = X.iloc[:cut], X.iloc[cut:cut + n_rows]
    rows = [part.iloc[i] for i in range(len(part))]  # Series named by their time (s), as a controller passes them
    own, own_cpu = per_update_ms(lambda: model.streamer(history), rows, repeats)
    generic, generic_cpu = per_update_ms(lambda: Streamer(model, history), rows, repeats)
    streamer = model.streamer(history)
    streamed = np.array([np.asarray(streamer.update(r), dtype=float).ravel() for r in rows])
    gap = float(np.abs(streamed - model.predict(part, history=history)).max())
    return {"model": name, "sized": sized, "history": model.history_length,
            "streamer": type(model.streamer(history)).__name__, "own_ms": own, "own_cpu_ms": own_cpu,
            "generic_ms": generic, "generic_cpu_ms": generic_cpu, "gap_um": gap}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="tiny", help="a registered dataset, or tiny (thermodrift.testing)")
    parser.add_argument("--models", nargs="+", default=None, help="default: every registered model")
    parser.add_argument("--epochs", type=int, default=2, help="training epochs of the torch models")
    parser.add_argument("--rows", type=int, default=50, help="rows streamed per pass")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    import torch

    from thermodrift.core import registry
    from thermodrift.testing import tiny_recording

    torch.set_num_threads(1)
    rec = tiny_recording() if args.dataset == "tiny" else registry.create("dataset", args.dataset)
    print(f"{args.dataset}: {len(rec.data)} rows; {args.rows} rows streamed x {args.repeats} passes; 1 torch "
          f"thread; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'model':22s}{'history':>8s}  {'streamer':25s}{'ms/update':>10s}{'cpu ms':>8s}{'generic ms':>11s}"
          f"{'cpu ms':>8s}{'speed-up':>9s}{'max |stream - batch| µm':>25s}")
    for name in args.models or registry.names("model"):
        r = measure(name, rec, args.epochs, args.rows, args.repeats)
        history = "all" if r["history"] is None else str(r["history"])
        label = name if r["sized"] == "defaults" else f"{name} ({r['sized']})"
        print(f"{label:22s}{history:>8s}  {r['streamer']:25s}{r['own_ms']:10.3f}{r['own_cpu_ms']:8.3f}"
              f"{r['generic_ms']:11.3f}{r['generic_cpu_ms']:8.3f}{r['generic_cpu_ms'] / r['own_cpu_ms']:8.1f}x"
              f"{r['gap_um']:25.2e}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
