"""The table of jobs a person reads: one line per MLflow job run, its components, held-out RMSE per target (µm)
with the baselines' beside it, and wall time (s). A grid prints it at its end; any verb that reports on runs
read back from MLflow (e.g. a later ``thermodrift report``) builds it with :func:`runs_table`.
"""

from __future__ import annotations

import pandas as pd

COMPONENTS = ("dataset", "selector", "model", "optimizer", "split")
BASELINES = ("mlr", "persistence")


def runs_table(runs) -> pd.DataFrame:
    """One row per MLflow run (``mlflow.entities.Run``) in the given order. Columns: the components (tags; the
    dataset is the recording file's name when there is one),
    ``rmse <target>``, then ``mlr <target>`` and ``persistence <target>`` per target channel (µm, held-out,
    mean over folds), ``rmse`` (mean over targets), ``wall_s`` and ``status``. Failed jobs keep their row."""
    rows = []
    for run in runs:
        tags, metrics = run.data.tags, run.data.metrics
        row = {c: tags.get(c, "") for c in COMPONENTS}
        row["dataset"] = tags.get("recording") or row["dataset"]  # a recording file's name says more
        for target in _targets(tags):
            row[f"rmse {target}"] = metrics.get(f"test/{target}/rmse")
            for base in BASELINES:
                row[f"{base} {target}"] = metrics.get(f"baseline/{base}/test/{target}/rmse")
        row["rmse"] = metrics.get("test/rmse")
        end = run.info.end_time or run.info.start_time
        row["wall_s"] = (end - run.info.start_time) / 1000.0 if run.info.start_time else None
        row["status"] = run.info.status
        rows.append(row)
    return pd.DataFrame(rows)


def format_table(table: pd.DataFrame) -> str:
    """The table as aligned text (µm with 3 decimals, wall time in whole s; a missing value is ``-``)."""
    if table.empty:
        return "(no jobs)"
    out = table.copy()
    for col in out.columns:
        if col == "wall_s":
            out[col] = out[col].map(lambda v: "-" if pd.isna(v) else f"{v:.0f}")
        elif out[col].dtype.kind == "f" or col.startswith(("rmse", *BASELINES)):
            out[col] = out[col].map(lambda v: "-" if v is None or pd.isna(v) else f"{float(v):.3f}")
    return out.to_string(index=False)


def _targets(tags: dict) -> list[str]:
    """Target channel names as logged (MLflow-safe) in the ``targets`` tag, comma separated."""
    return [t for t in tags.get("targets", "").split(",") if t]
