"""The leaderboard: one row per candidate (failures included) and the chosen ensemble (the one-SE average or the
greedy ensemble, its ``kind`` in ``params``), as CSV and Markdown.

Columns: ``rank`` (by ``inner_score``; failed rows last), ``trial``, ``model`` (the registry name of the inner
model, or ``ensemble``), ``settings`` (the model's settings, short; empty: its defaults), ``selector``,
``features``, ``rung`` (a network's fidelity), ``phase`` (portfolio, tpe, rung<k>, ensemble), ``status`` (ok,
failed), ``inner_score`` ((mean + worst) / 2 of the fold RMSEs, µm), ``fold<k>_rmse`` (µm, mean over targets),
``rmse <target>`` (µm, mean over folds), ``fit_s`` (s, all folds), ``latency_batch_ms`` and ``latency_stream_ms``
(ms per row), ``n_parameters``, ``params`` (the pipeline's parameters as JSON), ``error``; the automl job adds
``inner_extrapolated`` and ``never_extrapolated`` (:func:`thermodrift.core.automl.extrapolation.mark`). Timing
columns depend on the machine; every other column is deterministic for a seed and budget.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from thermodrift.core.automl import space

TIMING = ("fit_s", "latency_batch_ms", "latency_stream_ms")


def table(entries, folds, targets: list[str], ensemble: dict | None = None) -> pd.DataFrame:
    """The leaderboard of ``entries`` (``search.Entry``) on ``folds`` for ``targets``."""
    rows = []
    for e in entries:
        p = e.candidate.params
        _, selector, features = space.describe(p).split(" · ")
        row = {"trial": e.number, "model": p["model"], "settings": space.settings(p), "selector": selector,
               "features": features,
               "rung": e.candidate.rung, "phase": e.phase, "status": "ok" if e.evaluation is not None else "failed",
               "inner_score": e.score if e.evaluation is not None else np.nan}
        ev = e.evaluation
        for k in range(len(folds)):
            row[f"fold{k + 1}_rmse"] = ev.fold_rmse[k] if ev is not None else np.nan
        for t in targets:
            row[f"rmse {t}"] = ev.target_rmse.get(t, np.nan) if ev is not None else np.nan
        costs = ev.costs if ev is not None else {}
        row.update({"fit_s": ev.fit_s if ev is not None else np.nan,
                    "latency_batch_ms": costs.get("latency_batch_ms", np.nan),
                    "latency_stream_ms": costs.get("latency_stream_ms", np.nan),
                    "n_parameters": costs.get("n_parameters", np.nan),
                    "params": json.dumps(p, sort_keys=True, default=str), "error": e.error})
        rows.append(row)
    if ensemble is not None:
        row = {"trial": -1, "model": "ensemble", "settings": "", "selector": "", "features": "",
               "rung": 0, "phase": "ensemble", "status": "ok", "inner_score": ensemble["score"],
               **{f"fold{k + 1}_rmse": v for k, v in enumerate(ensemble["fold_rmse"])},
               "params": json.dumps({"members": ensemble["numbers"], "weights": ensemble["weights"],
                                     "kind": ensemble["kind"]}), "error": ""}
        rows.append(row)
    frame = pd.DataFrame(rows)
    frame = frame.sort_values(["inner_score", "trial"], na_position="last", kind="stable").reset_index(drop=True)
    frame.insert(0, "rank", np.arange(1, len(frame) + 1))
    return frame


def markdown(frame: pd.DataFrame, top: int | None = 20) -> str:
    """A Markdown table of the leaderboard's main columns (the ``top`` rows; None: all)."""
    cols = [c for c in frame.columns if c not in ("params", "phase", "rung")]
    part = frame[cols] if top is None else frame[cols].head(top)
    head = "| " + " | ".join(cols) + " |"
    rule = "|" + "|".join("---:" if pd.api.types.is_numeric_dtype(part[c]) else "---" for c in cols) + "|"
    lines = [head, rule]
    for _, r in part.iterrows():
        cells = []
        for c in cols:
            v = r[c]
            if isinstance(v, float):
                cells.append("" if np.isnan(v) else f"{v:.3f}" if abs(v) < 1e4 else f"{v:.3g}")
            else:
                cells.append(str(v).replace("|", "/")[:120])
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
