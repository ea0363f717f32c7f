"""S3's deep models at their default (CPU) size on the motorized_spindle_s3 recording: training time, the
efficiency table (S3 Table 14: inference latency per sample in a batch and one sample per call, parameter count)
and held-out accuracy (µm) next to MLR.

Inputs are the 16 sensors (°C), target z_drift (µm), split chronological (last 30 % of time held out), each model
with its constructor defaults, seed 0. Streaming latency is ``streamer(history).update(row)`` per call over the first
100 held-out rows.

    python benchmarks/bench_s3_models.py                    # every S3 model and bp, lstm, mlr; 1 torch thread
    python benchmarks/bench_s3_models.py --models dltk bp --threads 1
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np

MODELS = ["bp", "lstm", "cnn_lstm", "ma_cnn", "cnn_lstm_transformer", "tcn_lstm", "dltk"]


def measure(name: str, rec, sensors: list[str], y, cut: int, params: dict | None = None) -> dict:
    """Fit ``name`` on rows < ``cut``; return its costs (core/efficiency.py), epochs run and held-out metrics (µm)."""
    from thermodrift.core import efficiency, registry
    from thermodrift.core.metrics import evaluate
    from thermodrift.core.study import model_inputs

    model = registry.create("model", name, **(params or {}))
    X = model_inputs(rec, sensors, type(model), list(y.columns))  # plus the speed etc. a model reads
    start, cpu = time.perf_counter(), time.process_time()
    model.fit(X.iloc[:cut], y.iloc[:cut])
    cpu = time.process_time() - cpu  # CPU seconds: what the fit costs on an idle core, even on a busy machine
    cost = efficiency.measure(model, X, np.arange(cut, len(X)), time.perf_counter() - start)
    metrics = evaluate(y.iloc[cut:], model.predict(X.iloc[cut:], history=X.iloc[:cut]))["mean"]
    report = getattr(model, "train_report_", None)
    return {"model": name, **cost, "train_cpu_s": cpu, "epochs": getattr(report, "epochs_run", 0),
            **metrics}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=MODELS + ["mlr"])
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (1 is fastest for these sizes)")
    parser.add_argument("--device", default="cpu", help="cpu, cuda or auto")
    args = parser.parse_args(argv)
    import torch

    from thermodrift.core import registry
    from thermodrift.core.recording import TEMPERATURE_ROLES

    torch.set_num_threads(args.threads)
    rec = registry.create("dataset", "motorized_spindle_s3")
    X = rec.data[[c for r in TEMPERATURE_ROLES for c in rec.columns(r)]]
    y = rec.data[rec.columns("displacement")]
    cut = int(0.7 * len(X))
    print(f"motorized_spindle_s3: {len(X)} samples x {X.shape[1]} sensors; train {cut}, test {len(X) - cut} "
          f"(last 30 % of time); torch threads {args.threads}, device {args.device}; {platform.processor() or ''} "
          f"{torch.backends.cpu.get_cpu_capability()}; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    head = (f"{'model':22s}{'train s':>9s}{'cpu s':>7s}{'epochs':>7s}{'params':>9s}{'batch ms/sample':>17s}"
            f"{'stream ms/call':>16s}"
            f"{'RMSE µm':>9s}{'MAE µm':>8s}{'R2':>7s}")
    print(head)
    for name in args.models:
        params = {"trainer__device": args.device} if registry.accepts(registry.get("model", name).factory,
                                                                     "trainer") else {}
        r = measure(name, rec, list(X.columns), y, cut, params)
        print(f"{name:22s}{r['train_s']:9.1f}{r['train_cpu_s']:7.1f}{r['epochs']:7d}{r['n_parameters']:9.0f}"
              f"{r['latency_batch_ms']:17.4f}"
              f"{r['latency_stream_ms']:16.3f}"
              f"{r['rmse']:9.3f}{r['mae']:8.3f}{r['r2']:7.3f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
