"""S3's deep models at their default (CPU) size on the motorized_spindle_s3 recording: training time, the
efficiency table (S3 Table 14: inference latency per sample in a batch and one sample per call, parameter count)
and held-out accuracy (µm) next to MLR.

Inputs are the 16 sensors (°C), target z_drift (µm), split chronological (last 30 % of time held out), each model
with its constructor defaults, seed 0. Streaming latency is ``streamer(history).update(row)`` per call.

    python benchmarks/bench_s3_models.py                    # every S3 model, defaults, torch threads = 2
    python benchmarks/bench_s3_models.py --models dltk bp --threads 1 --stream-rows 200
"""

from __future__ import annotations

import argparse
import platform
import sys
import time

import numpy as np

MODELS = ["bp", "cnn_lstm", "ma_cnn", "cnn_lstm_transformer", "tcn_lstm", "dltk"]


def measure(name: str, X_train, y_train, X_test, y_test, stream_rows: int, params: dict | None = None) -> dict:
    """Fit ``name`` and return training s, parameter count, latencies (ms per sample) and held-out metrics (µm)."""
    from thermodrift.core import registry
    from thermodrift.core.metrics import evaluate

    model = registry.create("model", name, **(params or {}))
    start = time.perf_counter()
    model.fit(X_train, y_train)
    train_s = time.perf_counter() - start
    start = time.perf_counter()
    pred = model.predict(X_test, history=X_train)
    batch_ms = (time.perf_counter() - start) * 1e3 / len(X_test)
    streamer = model.streamer(X_train)
    rows = X_test.iloc[:stream_rows].to_dict("records")
    start = time.perf_counter()
    for row in rows:
        streamer.update(row)
    stream_ms = (time.perf_counter() - start) * 1e3 / len(rows)
    n_params = model.n_parameters() if hasattr(model, "n_parameters") else _count(model)
    metrics = evaluate(y_test, pred)["mean"]
    return {"model": name, "train_s": train_s, "params": n_params, "batch_ms": batch_ms, "stream_ms": stream_ms,
            "epochs": getattr(getattr(model, "train_report_", None), "epochs_run", 0), **metrics}


def _count(model) -> int:
    state = getattr(model, "state_dict_", None)
    if state is not None:
        return int(sum(v.numel() for v in state.values()))
    coef = getattr(model, "coef_", None)
    return int(np.size(coef) + np.size(getattr(model, "intercept_", 0))) if coef is not None else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=MODELS + ["mlr"])
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    parser.add_argument("--stream-rows", type=int, default=100, help="rows streamed one per call")
    parser.add_argument("--device", default="cpu", help="cpu, cuda or auto")
    args = parser.parse_args(argv)
    import torch

    from thermodrift.core import registry

    torch.set_num_threads(args.threads)
    rec = registry.create("dataset", "motorized_spindle_s3")
    roles = ("temperature", "ambient", "coolant_inlet", "coolant_outlet")
    X = rec.data[[c for r in roles for c in rec.columns(r)]]
    y = rec.data[rec.columns("displacement")]
    cut = int(0.7 * len(X))
    print(f"motorized_spindle_s3: {len(X)} samples x {X.shape[1]} sensors; train {cut}, test {len(X) - cut} "
          f"(last 30 % of time); torch threads {args.threads}, device {args.device}; {platform.processor() or ''} "
          f"{torch.backends.cpu.get_cpu_capability()}")
    head = (f"{'model':22s}{'train s':>9s}{'epochs':>7s}{'params':>9s}{'batch ms/sample':>17s}{'stream ms/call':>16s}"
            f"{'RMSE µm':>9s}{'MAE µm':>8s}{'R2':>7s}")
    print(head)
    for name in args.models:
        factory = registry.get("model", name).factory
        params = {"device": args.device} if registry.accepts(factory, "device") else {}
        r = measure(name, X[:cut], y[:cut], X[cut:], y[cut:], args.stream_rows, params)
        print(f"{name:22s}{r['train_s']:9.1f}{r['epochs']:7d}{r['params']:9d}{r['batch_ms']:17.4f}{r['stream_ms']:16.3f}"
              f"{r['rmse']:9.3f}{r['mae']:8.3f}{r['r2']:7.3f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
