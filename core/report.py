"""The published studies' tables from MLflow: one builder for ``thermodrift report`` and a sweep's summary.

:func:`collect` reads every job run under a sweep's parent run into one long table: a row per (job, fold,
prediction source), the source being the job's tuned model (``<model> (<optimizer>)``) or a baseline refitted
with its defaults on the same rows. The studies' tables are views of it:

* :func:`s1_table` — S1's Table 7 analogue: relative error %, mean residual (mean |e|, µm), MSE (µm²) and max
  residual (µm) per protocol, split and source (fold means).
* :func:`s2_table` — S2's analogue: mean relative error % and residual variance (µm²) per held-out block
  (S2's "inside the training range" and "beyond it" are the blocks of its paper protocols).
* :func:`grid_summary` — the held-out RMSE, MAE and max |e| of every job's model beside its baselines.
* S3's tables, written only for sweeps they apply to: :func:`s3_table13` (RMSE, MSE, MAE, R², EV, VAF per
  protocol, split and source; sweeps with a ``dltk`` job), :func:`s3_rmse_reduction` (DLTK's RMSE reduction
  against every other source, BP, LSTM and TCN-LSTM first), :func:`s3_efficiency` (Table 14: training s, latency
  per sample in a batch and per one-sample call, parameters), :func:`s3_ablation` (jobs tagged ``ablation=``
  full, no_deform, ...) and :func:`s3_table16` (the selector's inner optimizers: best |r| and the iteration it
  was first reached; sweeps over two or more of them).
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

METRICS = ("rmse", "mse", "mae", "max_abs_error", "mean_error", "relative_error_pct", "r2", "explained_variance",
           "vaf")
EFFICIENCY = {"train_s": "training s", "latency_batch_ms": "ms per sample (batch)",
              "latency_stream_ms": "ms per one-sample call", "n_parameters": "parameters"}
SELECTOR_METRICS = ("best_fitness", "best_iteration")  # a selector's ``metrics_`` (hdbscan_pso: S3 Table 16)
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
    """One row per (job run, fold, source) under ``parent_id`` with the job's tags and the fold's metrics; a
    baseline evaluated identically by several jobs has one row (that of the first job by run id)."""
    parent = client.get_run(parent_id)
    children = client.search_runs([parent.info.experiment_id], f"tags.mlflow.parentRunId = '{parent_id}'")
    rows = []
    for run in children:
        tags, params, metrics = run.data.tags, run.data.params, run.data.metrics
        folds = sorted({int(k.split("/")[0][4:]) for k in metrics if k.startswith("fold") and "/" in k})
        split = split_label(tags, params)  # two configs of one split kind (S1's 360/60 and 80/20) stay apart
        base = {"run_id": run.info.run_id, **{t: tags.get(t) for t in ("dataset", "model", "optimizer",
                                                                        "selector", "protocol", "ablation")},
                "split": split, "selected_sensors": params.get("selected_sensors", ""),
                "selector_optimizer": params.get("selector.params.optimizer"),
                **{f"selector_{m}": metrics.get(f"selector/{m}", np.nan) for m in SELECTOR_METRICS}}
        cost = {k: metrics.get(f"efficiency/{k}", np.nan) for k in EFFICIENCY}  # the job's model only
        for k in folds:
            prefixes = {f"{tags.get('model')} ({tags.get('optimizer')})": f"fold{k}/test/"}
            for key in metrics:
                if key.startswith(f"fold{k}/baseline/") and key.endswith("/test/rmse"):
                    prefixes[key.split("/")[2]] = key.removesuffix("rmse")
            for source, prefix in prefixes.items():
                tuned = prefix == f"fold{k}/test/"
                rows.append({**base, "fold": k, "fold_name": params.get(f"fold{k}/name", f"fold {k}"),
                             "source": source, "tuned": tuned,
                             **{m: metrics.get(prefix + m, np.nan) for m in METRICS},
                             **{c: v if tuned else np.nan for c, v in cost.items()}})
    table = pd.DataFrame(rows)
    if table.empty:
        raise InputError(f"run {parent_id} has no finished job runs with per-fold metrics",
                         hint="run a grid with `thermodrift run -m ...` first")
    table = table.sort_values(["protocol", "split", "run_id", "fold", "tuned", "source"],
                              ascending=[True, True, True, True, False, True], ignore_index=True)
    # Every job refits the baselines on its own rows: jobs that differ only in the model or optimizer evaluate
    # the same baseline on the same rows (same recording, selection, split and fold, equal metrics). That is
    # one evaluation, so it keeps one row and no table lists it once per job.
    same = ["dataset", "selector", "ablation", "protocol", "split", "fold", "selected_sensors", "source", *METRICS]
    return table[table["tuned"] | ~table.duplicated(same)].reset_index(drop=True)


def split_params(params: dict) -> dict[str, str]:
    """A job run's split parameters (logged ``split.params.<name>``), unset ones left out, by name."""
    return {k.removeprefix("split.params."): v for k, v in sorted(params.items())
            if k.startswith("split.params.") and v not in ("None", "null", "")}


def split_label(tags: dict, params: dict, only: set[str] | None = None) -> str:
    """The split of a job run: its kind (tag ``split``) with its parameters, e.g. ``paper_session (test=60,
    train=360, ...)``; ``only`` keeps those parameter names."""
    given = {k: v for k, v in split_params(params).items() if only is None or k in only}
    split = tags.get("split") or ""
    return f"{split} ({', '.join(f'{k}={v}' for k, v in given.items())})" if given else split


def best_jobs(runs) -> list:
    """The best finished job run of each protocol by inner validation RMSE (``valid/best_rmse``, never a held-out
    score), honest first. Validation RMSEs of different protocols come from different splits, so jobs are only
    compared within a protocol (tag ``protocol``); within one, compensation models come first (a job tagged
    ``reference``, such as persistence, only when all are)."""
    finished = [r for r in runs if r.info.status == "FINISHED" and "valid/best_rmse" in r.data.metrics]
    protocols = sorted({r.data.tags.get("protocol", "") for r in finished}, key=lambda p: (p != "honest", p))
    out = []
    for protocol in protocols:
        jobs = [r for r in finished if r.data.tags.get("protocol", "") == protocol]
        models = [r for r in jobs if "reference" not in r.data.tags] or jobs
        out.append(min(models, key=lambda r: r.data.metrics["valid/best_rmse"]))
    return out


def best_job_lines(best: list) -> list[str]:
    """One line per protocol's best job (:func:`best_jobs`), paper jobs labelled as such."""
    lines = []
    for run in best:
        protocol = run.data.tags.get("protocol", "")
        label = "" if protocol == "honest" else (
            " (protocol=paper: rows leak between train and test, not comparable with honest jobs)"
            if protocol == "paper" else f" (protocol={protocol or 'unknown'})")
        lines.append(f"best {'' if protocol == 'honest' else protocol + ' '}job by inner validation RMSE{label}: "
                     f"{run.info.run_name} ({run.info.run_id})")
    return lines


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


S3_METRICS = {"rmse": "RMSE µm", "mse": "MSE µm²", "mae": "MAE µm", "r2": "R²", "explained_variance": "EV",
              "vaf": "VAF %"}
S3_ABLATIONS = ("full", "no_deform", "no_lstm", "no_transformer", "no_kan")
S3_REDUCTION_FIRST = ("bp", "lstm", "tcn_lstm")  # S3 reports DLTK's RMSE reduction against these


def _comparison_rows(rows: pd.DataFrame) -> pd.DataFrame:
    """The rows of a comparison sweep with a ``dltk`` job (ablation children left out), else none."""
    plain = rows[~rows["ablation"].isin(S3_ABLATIONS)]
    return plain if (plain["tuned"] & (plain["model"] == "dltk")).any() else plain.iloc[:0]


def s3_table13(rows: pd.DataFrame) -> pd.DataFrame:
    """S3 Table 13/15 analogue: fold-mean RMSE, MSE, MAE (µm), R², EV and VAF % per protocol, split and source,
    best RMSE first; a baseline evaluated in several jobs on the same rows is averaged over them."""
    part = _comparison_rows(rows)
    out = part.groupby(["protocol", "split", "source"], sort=False)[list(S3_METRICS)].mean().reset_index()
    return out.sort_values(["protocol", "split", "rmse"], kind="stable").rename(columns=S3_METRICS) \
        .reset_index(drop=True)


def s3_rmse_reduction(rows: pd.DataFrame) -> pd.DataFrame:
    """DLTK's RMSE reduction % against every other source per protocol and split: 100 (1 − RMSE_dltk / RMSE_other);
    BP, LSTM and TCN-LSTM (S3's comparison) first."""
    part = _comparison_rows(rows)
    out = []
    for (protocol, split), block in part.groupby(["protocol", "split"], sort=False):
        dltk = block[block["tuned"] & (block["model"] == "dltk")]
        if dltk.empty:
            continue
        ours = dltk["rmse"].mean()
        means = block.groupby("source", sort=False)["rmse"].mean().drop(dltk["source"].unique())
        models = block[block["tuned"]].groupby("source")["model"].first()
        first = [s for m in S3_REDUCTION_FIRST for s in models.index[models == m] if s in means.index]
        for source in first + [s for s in means.index if s not in first]:
            out.append({"protocol": protocol, "split": split, "DLTK": dltk["source"].iloc[0], "against": source,
                        "RMSE µm": means[source], "DLTK RMSE µm": ours,
                        "RMSE reduction %": 100.0 * (1.0 - ours / means[source])})
    return pd.DataFrame(out)


def s3_efficiency(rows: pd.DataFrame) -> pd.DataFrame:
    """S3 Table 14 analogue: each job's refit model: training s, inference ms per sample (batch and one sample per
    call), parameter count, per protocol and split."""
    part = _comparison_rows(rows)
    part = part[part["tuned"]]
    out = part.groupby(["protocol", "split", "source"], sort=False)[list(EFFICIENCY)].mean().reset_index()
    out["n_parameters"] = out["n_parameters"].round().astype("Int64")
    return out.rename(columns=EFFICIENCY).reset_index(drop=True)


def s3_ablation(rows: pd.DataFrame) -> pd.DataFrame:
    """S3's ablation table: the jobs tagged ``ablation=full, no_deform, no_lstm, no_transformer, no_kan`` (fold
    means of the model's held-out metrics, its parameter count and training s)."""
    part = rows[rows["tuned"] & rows["ablation"].isin(S3_ABLATIONS)]
    cols = list(S3_METRICS) + ["n_parameters", "train_s"]
    out = part.groupby(["protocol", "split", "ablation", "source"], sort=False)[cols].mean().reset_index()
    out["n_parameters"] = out["n_parameters"].round().astype("Int64")
    out["order"] = out["ablation"].map(S3_ABLATIONS.index)
    out = out.sort_values(["protocol", "split", "order"], kind="stable").drop(columns="order")
    return out.rename(columns={**S3_METRICS, **EFFICIENCY}).reset_index(drop=True)


def s3_table16(rows: pd.DataFrame) -> pd.DataFrame:
    """S3 Table 16 analogue: the selector's inner optimizers on the selection task (best |Pearson r| of a cluster
    with the error, the iteration it was first reached, the chosen sensors), per protocol and split; written for
    sweeps that compare two or more of them."""
    part = rows.dropna(subset=["selector_best_fitness"]).drop_duplicates("run_id")
    if part["selector_optimizer"].nunique() < 2:
        return part.iloc[:0, :0]
    cols = {"selector_best_fitness": "best correlation", "selector_best_iteration": "reached at iteration",
            "selected_sensors": "sensors"}
    out = part[["protocol", "split", "selector", "selector_optimizer", *cols]].drop_duplicates()
    out["selector_best_iteration"] = out["selector_best_iteration"].round().astype(int)
    out = out.sort_values(["protocol", "split", "selector_best_fitness"], ascending=[True, True, False],
                          kind="stable")
    return out.rename(columns={"selector_optimizer": "optimizer", **cols}).reset_index(drop=True)


def markdown(table: pd.DataFrame, digits: int = 3) -> str:
    """A GitHub Markdown table (written here to avoid a dependency on ``tabulate`` for one small format)."""
    def cell(v) -> str:
        if isinstance(v, (float, np.floating)):
            return "–" if not np.isfinite(v) else f"{v:.{digits}f}"
        return str(v).replace("|", "\\|")
    head = "| " + " | ".join(str(c).replace("|", "\\|") for c in table.columns) + " |"
    rule = "|" + "|".join("---" for _ in table.columns) + "|"
    body = ["| " + " | ".join(cell(v) for v in row) + " |" for row in table.itertuples(index=False)]
    return "\n".join([head, rule, *body]) + "\n"


TABLES = {"s1_table7": ("S1 Table 7 analogue (held-out, fold means)", s1_table),
          "s2_mre": ("S2 analogue: mean relative error inside and beyond the training range", s2_table),
          "grid_summary": ("Grid summary", grid_summary),
          "s3_table13": ("S3 Table 13/15 analogue (held-out, fold means)", s3_table13),
          "s3_rmse_reduction": ("S3: DLTK's RMSE reduction against the other sources", s3_rmse_reduction),
          "s3_efficiency": ("S3 Table 14 analogue: efficiency of each job's refit model", s3_efficiency),
          "s3_ablation": ("S3 ablation of DLTK (held-out, fold means)", s3_ablation),
          "s3_table16": ("S3 Table 16 analogue: the selector's optimizers on the selection task", s3_table16)}


def write(rows: pd.DataFrame, folder: str | os.PathLike, title: str = "") -> dict[str, Path]:
    """Write every non-empty table of :data:`TABLES` as ``<name>.md`` and ``<name>.csv`` plus ``report.md`` into
    ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths, parts = {}, [f"# {title or 'thermodrift report'}\n"]
    for name, (heading, build) in TABLES.items():
        table = build(rows)
        if table.empty:  # a study's table that does not apply to this sweep
            continue
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
    dataset is the recording file's name when there is one; a split with the parameters that tell it apart from
    another of its kind in these runs), ``protocol``,
    ``rmse <target>``, then ``mlr <target>`` and ``persistence <target>`` per target channel (µm, held-out,
    mean over folds), ``rmse`` (mean over targets), ``wall_s`` and ``status``. Failed jobs keep their row."""
    runs = list(runs)
    # Runs of one split kind with different parameters (S1's 360/60 and 80/20 paper splits) are told apart by the
    # parameters that differ between them.
    by_kind: dict[str, list[dict]] = {}
    for run in runs:
        by_kind.setdefault(run.data.tags.get("split", ""), []).append(split_params(run.data.params))
    differing = {kind: {k for p in ps for k in p if len({str(q.get(k)) for q in ps}) > 1}
                 for kind, ps in by_kind.items()}
    rows = []
    for run in runs:
        tags, metrics = run.data.tags, run.data.metrics
        row = {c: tags.get(c, "") for c in COMPONENTS}
        row["dataset"] = tags.get("recording") or row["dataset"]  # a recording file's name says more
        row["split"] = split_label(tags, run.data.params, differing[tags.get("split", "")])
        row["protocol"] = tags.get("protocol", "")
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
