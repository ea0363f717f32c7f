"""The published studies' tables from MLflow: one builder for ``thermodrift report`` and a sweep's summary.

:func:`collect` reads every job run under a sweep's parent run into one long table: a row per (job, fold,
prediction source), the source being the job's tuned model (``<model> (<optimizer>)``) or a baseline refitted
with its defaults on the same rows. The studies' tables are views of it:

* :func:`s1_table` — S1's Table 7 analogue: relative error %, mean residual (mean |e|, µm), MSE (µm²) and max
  residual (µm) per protocol, split and source (fold means).
* :func:`s2_table` — S2's analogue: mean relative error % and residual variance (µm²) per held-out block
  (S2's "inside the training range" and "beyond it" are the blocks of its paper protocols).
* :func:`grid_summary` — the held-out RMSE, MAE and max |e| of every job's model beside its baselines.
* :func:`runs_table` / :func:`format_table` — the table a grid prints at its end: one line per job run with its
  components, held-out RMSE per target (µm) with the MLR and persistence baselines beside it, and wall time.

:func:`write` saves each as Markdown and CSV; :func:`log_to_parent` also attaches them to the parent run.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from thermodrift.core.errors import InputError

METRICS = ("rmse", "mse", "mae", "max_abs_error", "mean_error", "relative_error_pct", "r2")
S1_COLUMNS = {"relative_error_pct": "relative error %", "mae": "mean residual µm", "mse": "MSE µm²",
              "max_abs_error": "max residual µm"}


def parent_run(client, ref: str, experiment_ids: list[str] | None = None):
    """The parent run named by ``ref``: a run id, or a sweep id (tag ``sweep_id`` of a ``kind=sweep`` run)."""
    from mlflow.exceptions import MlflowException

    try:
        return client.get_run(ref)
    except MlflowException:
        pass
    ids = experiment_ids or [e.experiment_id for e in client.search_experiments()]
    runs = client.search_runs(ids, f"tags.sweep_id = '{ref}' and tags.kind = 'sweep'")
    if not runs:
        raise InputError(f"no MLflow run or sweep with id {ref!r} at {client.tracking_uri}",
                         hint="pass a sweep id (multirun/<id>) or a parent run id, and --tracking-uri")
    return runs[0]


def collect(client, parent_id: str) -> pd.DataFrame:
    """One row per (job run, fold, source) under ``parent_id`` with the job's tags and the fold's metrics."""
    parent = client.get_run(parent_id)
    children = client.search_runs([parent.info.experiment_id], f"tags.mlflow.parentRunId = '{parent_id}'")
    rows = []
    for run in children:
        tags, params, metrics = run.data.tags, run.data.params, run.data.metrics
        folds = sorted({int(k.split("/")[0][4:]) for k in metrics if k.startswith("fold") and "/" in k})
        split_params = {k.removeprefix("split.params."): v for k, v in sorted(params.items())
                        if k.startswith("split.params.") and v not in ("None", "null", "")}
        split = tags.get("split")
        if split_params:  # two configs of one split kind (S1's 360/60 and 80/20) stay apart
            split = f"{split} ({', '.join(f'{k}={v}' for k, v in split_params.items())})"
        base = {"run_id": run.info.run_id, **{t: tags.get(t) for t in ("dataset", "model", "optimizer",
                                                                        "selector", "protocol")}, "split": split,
                "selected_sensors": params.get("selected_sensors", "")}
        for k in folds:
            prefixes = {f"{tags.get('model')} ({tags.get('optimizer')})": f"fold{k}/test/"}
            for key in metrics:
                if key.startswith(f"fold{k}/baseline/") and key.endswith("/test/rmse"):
                    prefixes[key.split("/")[2]] = key.removesuffix("rmse")
            for source, prefix in prefixes.items():
                rows.append({**base, "fold": k, "fold_name": params.get(f"fold{k}/name", f"fold {k}"),
                             "source": source, "tuned": prefix == f"fold{k}/test/",
                             **{m: metrics.get(prefix + m, np.nan) for m in METRICS}})
    table = pd.DataFrame(rows)
    if table.empty:
        raise InputError(f"run {parent_id} has no finished job runs with per-fold metrics",
                         hint="run a grid with `thermodrift run -m ...` first")
    return table.sort_values(["protocol", "split", "run_id", "fold", "tuned", "source"],
                             ascending=[True, True, True, True, False, True], ignore_index=True)


def s1_table(rows: pd.DataFrame) -> pd.DataFrame:
    """S1 Table 7 analogue: fold-mean metrics per protocol, split and source (tuned models first)."""
    keys = ["protocol", "split", "source", "tuned"]
    out = rows.groupby(keys, sort=False)[list(S1_COLUMNS)].mean().reset_index()
    out = out.sort_values(["protocol", "split", "tuned"], ascending=[True, True, False], kind="stable")
    return out.drop(columns="tuned").rename(columns=S1_COLUMNS).reset_index(drop=True)


def s2_table(rows: pd.DataFrame) -> pd.DataFrame:
    """S2 analogue: mean relative error % and residual variance (µm²) per protocol, split, held-out block, source."""
    out = rows[["protocol", "split", "fold_name", "source", "tuned", "relative_error_pct", "mse", "mean_error"]].copy()
    out["residual variance µm²"] = out["mse"] - out["mean_error"] ** 2
    out = out.drop(columns=["mse", "mean_error"]).rename(columns={"relative_error_pct": "mean relative error %",
                                                                  "fold_name": "held-out block"})
    out = out.sort_values(["protocol", "split", "held-out block", "tuned"], ascending=[True, True, True, False],
                          kind="stable")
    return out.drop(columns="tuned").reset_index(drop=True)


def grid_summary(rows: pd.DataFrame) -> pd.DataFrame:
    """Every job's tuned model beside its baselines: fold-mean RMSE, MAE and max |e| (µm), R²."""
    keys = ["dataset", "selector", "split", "protocol", "source"]
    return rows.groupby(keys, sort=False)[["rmse", "mae", "max_abs_error", "r2"]].mean().reset_index()


def markdown(table: pd.DataFrame, digits: int = 3) -> str:
    """A GitHub Markdown table (written here to avoid a dependency on ``tabulate`` for one small format)."""
    def cell(v) -> str:
        if isinstance(v, (float, np.floating)):
            return "–" if not np.isfinite(v) else f"{v:.{digits}f}"
        return str(v).replace("|", "\\|")
    head = "| " + " | ".join(map(str, table.columns)) + " |"
    rule = "|" + "|".join("---" for _ in table.columns) + "|"
    body = ["| " + " | ".join(cell(v) for v in row) + " |" for row in table.itertuples(index=False)]
    return "\n".join([head, rule, *body]) + "\n"


TABLES = {"s1_table7": ("S1 Table 7 analogue (held-out, fold means)", s1_table),
          "s2_mre": ("S2 analogue: mean relative error inside and beyond the training range", s2_table),
          "grid_summary": ("Grid summary", grid_summary)}


def write(rows: pd.DataFrame, folder: str | os.PathLike, title: str = "") -> dict[str, Path]:
    """Write every table of :data:`TABLES` as ``<name>.md`` and ``<name>.csv`` plus ``report.md`` into ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths, parts = {}, [f"# {title or 'thermodrift report'}\n"]
    for name, (heading, build) in TABLES.items():
        table = build(rows)
        paths[f"{name}.csv"] = folder / f"{name}.csv"
        table.to_csv(paths[f"{name}.csv"], index=False)
        text = markdown(table)
        paths[f"{name}.md"] = folder / f"{name}.md"
        paths[f"{name}.md"].write_text(f"## {heading}\n\n{text}", encoding="utf-8")
        parts.append(f"## {heading}\n\n{text}")
    parts.append("Units: µm (MSE and variance µm²); protocol=paper rows reproduce a study's split, "
                 "protocol=honest rows hold out a whole working condition.\n")
    paths["report.md"] = folder / "report.md"
    paths["report.md"].write_text("\n".join(parts), encoding="utf-8")
    rows.to_csv(folder / "rows.csv", index=False)
    paths["rows.csv"] = folder / "rows.csv"
    return paths


def log_to_parent(client, parent_id: str, folder: str | os.PathLike | None = None) -> dict[str, Path]:
    """Build the tables of the sweep under ``parent_id``, write them (``folder`` or a temporary one) and attach
    them to the parent run under ``report/``."""
    rows = collect(client, parent_id)
    title = f"thermodrift report — sweep {client.get_run(parent_id).data.tags.get('sweep_id', parent_id)}"
    if folder is not None:
        paths = write(rows, folder, title)
        for path in paths.values():
            client.log_artifact(parent_id, str(path), artifact_path="report")
        return paths
    with tempfile.TemporaryDirectory() as tmp:
        paths = write(rows, tmp, title)
        for path in paths.values():
            client.log_artifact(parent_id, str(path), artifact_path="report")
    return {}


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
