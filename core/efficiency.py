"""What a fitted model costs (S3 Table 14): training time, inference latency per sample, parameter count.

Latency is read two ways, as a controller would call the model: in a batch (``predict`` over a block of rows with
its history, ms per row) and one row per call (``streamer(history).update(row)``, ms per call). The parameter
count is the number of trainable weights of a torch model (``train_report_.n_parameters``) or the size of a linear
model's coefficients (its own ``coef_`` or a fitted estimator's it holds); 0 where a model has neither.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from thermodrift.core.components import same_run

STREAM_ROWS = 100  # rows streamed one per call; enough for a stable mean, cheap for every model


def parameter_count(model) -> int:
    """Trainable parameters of a fitted model (see the module docstring); a composite model (a pipeline, an
    ensemble) counts those of the models its ``fitted_models()`` returns."""
    parts = getattr(model, "fitted_models", None)
    if callable(parts):
        return int(sum(parameter_count(m) for m in parts()))
    report = getattr(model, "train_report_", None)
    if report is not None and getattr(report, "n_parameters", 0):
        return int(report.n_parameters)
    state = getattr(model, "state_dict_", None)
    if state is not None:
        return int(sum(v.numel() for v in state.values()))
    # a linear model's coefficients, on the model or on a fitted scikit-learn estimator it holds
    for est in (model, *(v for k, v in vars(model).items() if k.endswith("_"))):
        coef = getattr(est, "coef_", None)
        if coef is not None:
            return int(np.size(coef) + np.size(getattr(est, "intercept_", 0)))
    return 0


def measure(model, frame: pd.DataFrame, rows: np.ndarray, train_seconds: float,
            stream_rows: int = STREAM_ROWS) -> dict[str, float]:
    """Efficiency of ``model`` on ``rows`` (sorted positions into ``frame``, its inputs for every recording row):
    ``train_s``, ``latency_batch_ms`` (per row, the first contiguous block predicted with the rows before it as
    history), ``latency_stream_ms`` (per ``update`` over up to ``stream_rows`` rows of that block) and
    ``n_parameters``."""
    block = np.split(rows, np.flatnonzero(np.diff(rows) != 1) + 1)[0] if len(rows) else rows
    history = same_run(frame.iloc[:int(block[0])], float(frame.index[block[0]])) if len(block) else frame.iloc[:0]
    start = time.perf_counter()
    model.predict(frame.iloc[block], history=history)
    batch_ms = (time.perf_counter() - start) * 1e3 / max(1, len(block))
    streamer = model.streamer(history)
    # rows as a controller passes them: Series named by their time (a physics model steps its state by it)
    part = frame.iloc[block[:stream_rows]]
    records = [part.iloc[i] for i in range(len(part))]
    start = time.perf_counter()
    for row in records:
        streamer.update(row)
    stream_ms = (time.perf_counter() - start) * 1e3 / max(1, len(records))
    return {"train_s": float(train_seconds), "latency_batch_ms": batch_ms, "latency_stream_ms": stream_ms,
            "n_parameters": float(parameter_count(model))}
