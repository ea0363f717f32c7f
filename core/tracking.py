"""MLflow tracking: a parent run per sweep, a child run per job, trial metrics, figures and the final model.

Job runs are named ``<dataset> · <model> · <optimizer> · <selector> · <split>`` and carry the recording as an
MLflow dataset input. Tags on every job run: ``dataset``, ``selector``, ``model``, ``optimizer``, ``split``,
``ablation`` (so the MLflow UI groups and compares them), ``recording``, ``targets``, ``protocol``,
``optuna.study`` (the study names, one per fold) and ``optuna.storage``; ``same_as`` when the model's held-out
predictions equal a baseline's. Metric names: ``test/<metric>`` (mean over displacement channels and folds),
``test/<channel>/<metric>``, ``baseline/<name>/test/<metric>``, ``baseline/<name>/test/<channel>/rmse``,
``trial/value`` and ``trial/best`` per trial (``fold<k>/trial/...`` with several folds), all in µm except R²,
explained variance, VAF (%), relative error (%) and compensation rate.
Efficiency metrics per job: ``efficiency/train_s``, ``efficiency/latency_batch_ms``, ``efficiency/latency_stream_ms``
(ms per sample) and ``efficiency/n_parameters``.

The physics verbs log here too (:func:`log_calibration`, :func:`log_diagnosis`): physics computes and returns
its results and never imports this module.
"""

from __future__ import annotations

import json
import logging
import os
import re
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import mlflow
import numpy as np
import optuna
import pandas as pd
from hydra.experimental.callback import Callback
from mlflow.entities import Metric, Param
from mlflow.tracking import MlflowClient

from thermodrift.compensator import package
from thermodrift.core import artifacts, deployment
from thermodrift.core.tracking_faults import DEFAULT_URI

PARENT_ENV = "THERMODRIFT_PARENT_RUN_ID"
TAGS = ("dataset", "selector", "model", "optimizer", "split", "ablation")
FIGURES = "figures"  # artifact folder of a job run's figures


def setup(uri: str | None, experiment: str) -> str:
    """Point MLflow at ``uri`` (default :data:`DEFAULT_URI`) with telemetry off; return the experiment id."""
    os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
    for name in ("mlflow", "alembic"):  # schema-migration and "creating experiment" chatter
        logging.getLogger(name).setLevel(logging.WARNING)
    uri = uri or DEFAULT_URI
    mlflow.set_tracking_uri(uri)
    if mlflow.get_experiment_by_name(experiment) is None and uri.startswith("sqlite:///"):
        # Artifacts beside the database file, not in whatever folder the first run happened to start from.
        db = Path(uri.removeprefix("sqlite:///"))
        try:
            mlflow.create_experiment(experiment, artifact_location=(db.parent.resolve() / "mlruns").as_uri())
        except mlflow.exceptions.MlflowException:  # a parallel job created it first
            pass
    return mlflow.set_experiment(experiment).experiment_id


def metric_key(*parts: str) -> str:
    """An MLflow-safe metric name (channel names such as ``ch3(um)`` contain characters MLflow refuses)."""
    return "/".join(re.sub(r"[^0-9A-Za-z_\-. :]", "_", str(p)) for p in parts)


class TrialLogger:
    """Optuna callback logging each finished trial's value and the running best to the active MLflow run
    (steps: trial numbers; a job with several folds logs ``fold<k>/trial/...`` per fold's study).

    Written here because optuna-integration's MLflowCallback is deprecated in Optuna 5 and opens a run per
    trial; we want trial curves inside the job's run.
    """

    def __init__(self, run_id: str):
        self.run_id = run_id
        self.client = MlflowClient()

    def __call__(self, study: optuna.Study, trial: optuna.trial.FrozenTrial) -> None:
        best = study.best_value if trial.state == optuna.trial.TrialState.COMPLETE else None
        self._log(study, [(trial, best)])

    def replay(self, study: optuna.Study, upto: int) -> None:
        """Log the trials numbered below ``upto`` (those a resumed study found in its storage), with the running
        best as it was then."""
        rows, best = [], None
        for trial in study.trials[:upto]:
            if trial.state == optuna.trial.TrialState.COMPLETE and trial.value is not None:
                best = trial.value if best is None else min(best, trial.value)
            rows.append((trial, best))
        self._log(study, rows)

    def _log(self, study: optuna.Study, rows) -> None:
        fold = re.search(r"-fold(\d+)of\d+$", study.study_name)
        prefix = f"fold{fold[1]}/trial/" if fold else "trial/"
        stamp = int(time.time() * 1000)
        metrics = []
        for trial, best in rows:
            metrics.append(Metric(f"{prefix}{trial.state.name.lower()}", 1.0, stamp, trial.number))
            if trial.state == optuna.trial.TrialState.COMPLETE and trial.value is not None:
                metrics += [Metric(f"{prefix}value", float(trial.value), stamp, trial.number),
                            Metric(f"{prefix}best", float(best), stamp, trial.number)]
        for i in range(0, len(metrics), 900):  # MLflow takes at most 1000 metrics per batch
            self.client.log_batch(self.run_id, metrics=metrics[i:i + 900])


def run_name(spec) -> str:
    """The job's MLflow run name, dataset and model first: ``<dataset> · <model> · <optimizer> · <selector> ·
    <split>``; a recording file is named by its table's file name."""
    table = (spec.dataset_params or {}).get("table")
    dataset = Path(str(table)).name if table else spec.dataset
    return f"{dataset} · {spec.model} · {spec.optimizer} · {spec.selector} · {spec.split}"


def job_tags(names: dict[str, str], ablation: str, protocol: str) -> dict[str, str]:
    return {**{k: str(names[k]) for k in TAGS if k in names}, "ablation": str(ablation), "protocol": protocol}


def start_job_run(run_name: str, tags: dict[str, str]) -> mlflow.ActiveRun:
    """Start the job's run, nested under the sweep's parent run when there is one."""
    parent = os.environ.get(PARENT_ENV)
    if parent:
        tags = {**tags, "mlflow.parentRunId": parent}
    return mlflow.start_run(run_name=run_name, tags=tags)


def log_result(result, params: dict[str, Any]) -> None:
    """Log a :class:`~thermodrift.core.study.JobResult` into the active run: config params, the recording as a
    dataset input, the Optuna studies (tags ``optuna.study``, ``optuna.storage``), held-out metrics of the model
    and baselines (mean over targets and per target), the model's efficiency and the selector's ``metrics_``
    (fold means), figures and the last fold's refit model."""
    mlflow.log_params({k: _short(v) for k, v in flatten(params).items()})
    mlflow.log_param("selected_sensors", ",".join(result.selected))
    studies = [f.study.study_name for f in result.folds if f.study is not None]
    mlflow.set_tags({"targets": ",".join(metric_key(t) for t in result.targets), "unit": result.unit,
                     "optuna.study": _short(",".join(studies) or "none (n_trials=0: untuned)"),
                     "optuna.storage": str(result.spec.storage)})
    if result.same_as():
        mlflow.set_tag("same_as", result.same_as())
    if result.recording is not None:
        _log_dataset(result)
    trials = [t for f in result.folds if f.study is not None for t in f.study.trials]
    metrics = {"valid/best_rmse": result.valid_rmse,
               "study/n_trials": float(len(trials)),
               "study/n_failed": float(sum(t.state == optuna.trial.TrialState.FAIL for t in trials)),
               "study/n_diverged": float(sum(bool(t.user_attrs.get("diverged")) for t in trials))}
    for who in result.folds[0].metrics:
        prefix = ("test",) if who == "model" else ("baseline", who, "test")
        for name, value in result.summary_metrics(who).items():
            metrics[metric_key(*prefix, name)] = value
        for channel in result.targets:
            per = result.summary_metrics(who, channel)
            names = per if who == "model" else ["rmse"]
            metrics.update({metric_key(*prefix, channel, n): per[n] for n in names})
    for k, fold in enumerate(result.folds, 1):  # per fold too, so a report can tell a protocol's blocks apart
        mlflow.log_param(f"fold{k}/name", _short(fold.name))
        for who, per in fold.metrics.items():
            prefix = ("test",) if who == "model" else ("baseline", who, "test")
            metrics.update({metric_key(f"fold{k}", *prefix, n): v for n, v in per["mean"].items()})
    for base in (w for w in result.folds[0].metrics if w != "model"):
        ref = metrics[metric_key("baseline", base, "test", "rmse")]
        if ref > 0:
            metrics[metric_key("skill_vs", base)] = 1.0 - metrics["test/rmse"] / ref
    for key in result.folds[-1].efficiency:  # S3 Table 14: training s, latency ms per sample, parameter count
        metrics[metric_key("efficiency", key)] = float(np.mean([f.efficiency.get(key, np.nan) for f in result.folds]))
    selector_metrics = [getattr(f.selector, "metrics_", None) or {} for f in result.folds]
    for key in selector_metrics[-1]:  # a selector's own scalars (S3 Table 16: best |r|, the iteration it came)
        metrics[metric_key("selector", key)] = float(np.mean([m.get(key, np.nan) for m in selector_metrics]))
    mlflow.log_metrics({k: v for k, v in metrics.items() if np.isfinite(v)})
    mlflow.log_params({f"best/{k}": _short(v) for k, v in result.best_params.items()})
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        comparison(result).to_csv(tmp_path / "comparison.csv")
        mlflow.log_artifact(str(tmp_path / "comparison.csv"))
        for fig_name, fig in figures(result).items():
            fig.savefig(tmp_path / fig_name, dpi=110, bbox_inches="tight")
            mlflow.log_artifact(str(tmp_path / fig_name), artifact_path=FIGURES)
        for k, fold in enumerate(result.folds, 1):
            where = "selector" if len(result.folds) == 1 else f"selector/fold{k}"
            for name, path in selector_report(getattr(fold, "selector", None), tmp_path / where).items():
                mlflow.log_artifact(str(path), artifact_path=where)
    # Once per job, as an MLflow pyfunc model stored as data only (loading runs no code from the artifact).
    artifacts.log_model(result.model, result.spec.model)
    if result.recording is not None:  # limits.json and fallbacks/ for `thermodrift export`
        try:
            _log_export_parts(result)
        except Exception as exc:  # the job's results are logged; what export needs and failed is only noted
            mlflow.set_tag("compensator_error", _short(f"{type(exc).__name__}: {exc}"))


def _log_export_parts(result) -> None:
    """``limits.json`` and ``fallbacks/`` (:mod:`thermodrift.core.deployment`) beside the run's ``model``, or the
    tag ``compensator`` saying why the model cannot be exported."""
    reason = deployment.not_exportable(result)
    if reason:
        mlflow.set_tag("compensator", reason)
        return
    lim, fallbacks = deployment.export_parts(result)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / deployment.LIMITS
        path.write_text(json.dumps(lim, indent=1), encoding="utf-8")
        mlflow.log_artifact(str(path))
        if fallbacks:
            package.write({"fallbacks": fallbacks}, Path(tmp) / deployment.FALLBACKS)
            mlflow.log_artifacts(str(Path(tmp) / deployment.FALLBACKS), artifact_path=deployment.FALLBACKS)


def log_automl(result, config: dict) -> None:
    """Log an :class:`~thermodrift.core.automl.job.AutoMLResult` into the active run (the parent: held-out metrics
    as :func:`log_result` logs them, the leaderboard, the choice) and one child run per family tried."""
    from thermodrift.core.automl import leaderboard, space

    job = result.job
    chosen = {"name": job.spec.model, "params": job.spec.model_params}
    params = {k: v for k, v in config.items() if k not in ("model", "selector", "optimizer", "search_space",
                                                            "n_trials")}
    log_result(job, {**params, "model": chosen})  # with the model: limits.json, as `run` logs it
    best = result.search.best
    mlflow.set_tags({"model": job.spec.model, "protocol": job.protocol, "automl.chosen": result.describe()[:5000],
                     "automl.family": best.candidate.family, "automl.stopped_by": result.search.stopped_by})
    failed = int((result.leaderboard["status"] == "failed").sum())
    mlflow.set_tag("extrapolation", result.extrapolates()[:5000] or "none")
    mlflow.log_metrics({metric_key("extrapolation", e.driver, k): v for e in result.extrapolation
                        for k, v in (("beyond", e.beyond), ("share_of_span", e.share), ("rows", float(e.rows)))
                        if v < float("inf")})  # share: inf for a driver constant in training
    mlflow.log_metrics({"automl/fits": float(result.search.fits), "automl/candidates": float(len(result.leaderboard)),
                        "automl/failed": float(failed), "automl/wall_s": float(result.wall_s),
                        "automl/inner_score": float(job.valid_rmse)})
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "leaderboard.csv"
        result.leaderboard.to_csv(csv, index=False)
        (Path(tmp) / "leaderboard.md").write_text(leaderboard.markdown(result.leaderboard, top=None) + "\n",
                                                  encoding="utf-8")
        mlflow.log_artifact(str(csv))
        mlflow.log_artifact(str(Path(tmp) / "leaderboard.md"))
        (Path(tmp) / "chosen.json").write_text(json.dumps(chosen, indent=2, default=str), encoding="utf-8")
        mlflow.log_artifact(str(Path(tmp) / "chosen.json"))
    parent = mlflow.active_run().info.run_id
    board = result.leaderboard[result.leaderboard["model"] != "ensemble"]
    for family, rows in board.groupby("model", sort=True):
        ok = rows[rows["status"] == "ok"]
        with mlflow.start_run(run_name=f"automl candidate · {family}", nested=True,
                              tags={"kind": "automl_candidate", "model": str(family), "mlflow.parentRunId": parent,
                                    "dataset": job.spec.dataset, "split": job.spec.split}):
            metrics = {"automl/candidates": float(len(rows)), "automl/failed": float(len(rows) - len(ok))}
            if len(ok):
                top = ok.iloc[0]
                metrics["inner/score"] = float(top["inner_score"])
                metrics.update({metric_key("inner", c): float(top[c]) for c in ok.columns
                                if c.startswith(("fold", "rmse ")) and top[c] == top[c]})
                mlflow.log_param("best_params", str(top["params"])[:500])
                mlflow.log_param("best_label", space.describe(json.loads(top["params"]))[:500])
            else:
                mlflow.set_tag("error", str(rows.iloc[0]["error"])[:5000])
            mlflow.log_metrics(metrics)


def fail_run(exc: BaseException) -> None:
    """End the active run as FAILED with the error as its tag ``error``."""
    mlflow.set_tag("error", str(exc)[:5000])
    mlflow.end_run(status="FAILED")


def set_tag(key: str, value: str) -> None:
    """Tag the active run."""
    mlflow.set_tag(key, value)


def client() -> MlflowClient:
    """A client of the current tracking store (the one :func:`setup` pointed MLflow at)."""
    return MlflowClient()


def logged_run(uri: str, run_id: str):
    """The MLflow run ``run_id`` at ``uri`` (after :func:`setup`); InputError when there is none."""
    from mlflow.exceptions import MlflowException

    from thermodrift.core.errors import InputError

    setup(uri, "thermodrift")
    try:
        return client().get_run(run_id)
    except MlflowException:
        raise InputError(f"no MLflow run {run_id!r} at {uri}",
                         hint="pass the id that `thermodrift run` printed and the same --tracking-uri") from None


def artifact_paths(run_id: str) -> set[str]:
    """The paths at the artifact root of run ``run_id``."""
    return {a.path for a in client().list_artifacts(run_id)}


def download(uri: str, run_id: str, path: str | None, dst: str | Path) -> Path | None:
    """Run ``run_id``'s artifact ``path`` (None: all of them) downloaded into ``dst``; None when it is missing."""
    from mlflow.exceptions import MlflowException

    os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")
    try:
        if path is None:
            return Path(mlflow.artifacts.download_artifacts(run_id=run_id, dst_path=str(dst), tracking_uri=uri))
        return Path(mlflow.artifacts.download_artifacts(artifact_uri=f"runs:/{run_id}/{path}", dst_path=str(dst),
                                                        tracking_uri=uri))
    except MlflowException:
        if path is None:
            raise
        return None


def drop_active_runs() -> None:
    """Forget the runs this process has open after the server went away (ending them would fail too); the
    next job of the same study closes them as KILLED."""
    from thermodrift.core import tracking_faults

    while mlflow.active_run() is not None:
        try:
            mlflow.end_run(status="FAILED")
        except tracking_faults.failures():
            from mlflow.tracking import fluent

            stack = fluent._active_run_stack.get()  # mlflow has no public way to drop a run it cannot end
            stack.pop()


def _log_dataset(result) -> None:
    """The recording as the run's MLflow dataset input (name, source, digest and schema in the runs table)."""
    import mlflow.data

    rec = result.recording
    name = run_name(result.spec).split(" · ")[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # mlflow's notes on schema inference for integer columns
        dataset = mlflow.data.from_pandas(rec.data.reset_index(), source=str(rec.source), name=name)
        for attempt in (1, 2, 3):
            try:
                mlflow.log_input(dataset, context="recording")
                return
            except Exception as exc:  # noqa: BLE001 - MLflow wraps the database error in its own types
                # MLflow's store looks the dataset up, then inserts it: two runs logging one recording at the same
                # moment collide on its unique key; the retry finds the row the other run wrote.
                if attempt == 3 or not any(s in str(exc) for s in ("UNIQUE constraint", "duplicate key")):
                    raise


def selector_report(selector, folder: Path) -> dict[str, Path]:
    """Write a fitted selector's ``report_`` tables (CSV) and ``report_figures()`` (PNG) into ``folder``."""
    tables = getattr(selector, "report_", None) or {}
    draw = getattr(selector, "report_figures", None)
    if not tables and draw is None:
        return {}
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for name, table in tables.items():
        out[name] = folder / f"{name}.csv"
        table.to_csv(out[name], index=not isinstance(table.index, pd.RangeIndex))
    for name, fig in (draw() if callable(draw) and tables else {}).items():
        out[name] = folder / name
        fig.savefig(out[name], dpi=110, bbox_inches="tight")
    return out


def comparison(result) -> pd.DataFrame:
    """Held-out metrics (channel mean, averaged over folds) of the model and each baseline, one row each."""
    rows = {_label(result, who): result.summary_metrics(who)
            for who in result.folds[0].metrics}
    return pd.DataFrame(rows).T


# One style per prediction source, so no curve hides another (persistence lies one sample behind the measurement).
_STYLES = {"measured": dict(color="0.55", lw=2.6, ls="-"), "model": dict(color="C0", lw=1.3, ls="-"),
           "persistence": dict(color="C3", lw=1.0, ls=":"), "mlr": dict(color="C2", lw=1.1, ls="--")}
_OTHER = [dict(color=c, lw=1.1, ls=ls) for c, ls in (("C4", "-."), ("C1", (0, (5, 1, 1, 1))), ("C5", "--"))]


def log_horizons(result, horizons_h: list[float]):
    """Held-out RMSE per forecast horizon (:func:`thermodrift.core.horizons.scores`) into the active run as
    ``horizon/<label>/rmse`` (the model) and ``baseline/<name>/horizon/<label>/rmse``; returns the table (None
    without horizons)."""
    if not horizons_h:
        return None
    from thermodrift.core import horizons

    table = horizons.scores(result, horizons_h)
    metrics = {}
    for who, row in table.iterrows():
        prefix = ("horizon",) if str(who).startswith("model: ") else ("baseline", str(who), "horizon")
        metrics.update({metric_key(*prefix, h.replace(" ", "_"), "rmse"): float(v) for h, v in row.items()})
    mlflow.log_metrics(metrics)
    return table


def horizon_lines(table, unit: str) -> list[str]:
    """The report's lines for :func:`log_horizons`' table (none without horizons)."""
    if table is None:
        return []
    return [f"held-out RMSE by forecast horizon, {unit} (a model that reads only inputs predicts the same at every "
            "horizon; persistence reads the target as old as the horizon):", table.to_string(float_format="%.3f")]


def figures(result) -> dict[str, Any]:
    """Prediction vs measurement and residuals on the last fold (RMSE per curve in the legend), and the
    convergence of each fold's study. Plain matplotlib Figures, outside pyplot's registry, so a grid running many
    jobs in one process does not pile up open figures."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    out = {}
    fold = result.folds[-1]
    hours = fold.time_s / 3600.0
    k = fold.y_true.shape[1]
    title = f"{run_name(result.spec)} — {held_out(fold.name)}"
    styles = {who: _STYLES.get(who, _OTHER[i % len(_OTHER)]) for i, who in enumerate(fold.predictions)}

    def error_unit(col: str) -> str:  # µm for a displacement, K for a temperature
        channel = getattr(result.recording, "channels", {}).get(col)
        return "K" if channel is not None and channel.role == "temperature" else "µm"

    def legend_label(who: str, col: str) -> str:
        return f"{_label(result, who)} (RMSE {fold.metrics[who][col]['rmse']:.2f} {error_unit(col)})"

    for fig_name, residual in (("prediction_vs_measurement.png", False), ("residuals.png", True)):
        fig = Figure(figsize=(9, 2.6 * k + 0.4))
        axes = fig.subplots(k, 1, squeeze=False, sharex=True)
        for i, col in enumerate(fold.y_true.columns):
            ax, y = axes[i, 0], fold.y_true[col].to_numpy()
            if residual:
                ax.axhline(0, color="0.3", lw=0.6)
            else:
                ax.plot(hours, y, label="measured", **_STYLES["measured"])
            for who, pred in fold.predictions.items():
                ax.plot(hours, y - pred[:, i] if residual else pred[:, i], label=legend_label(who, col),
                        **styles[who])
            unit = error_unit(col)
            ax.set_ylabel(f"{'residual ' if residual else ''}{col} [{unit if residual or unit != 'K' else '°C'}]")
            ax.legend(fontsize=7, loc="best")
        axes[-1, 0].set_xlabel("time [h]")
        fig.suptitle(("residual (measured − predicted): " if residual else "") + title, fontsize=9)
        out[fig_name] = fig
    studies = [(f.name, f.study) for f in result.folds if f.study is not None]
    if any(t.value is not None for _, s in studies for t in s.trials):
        fig = Figure(figsize=(6.5, 3.8))
        ax = fig.subplots()
        for i, (name, study) in enumerate(studies):
            done = [t for t in study.trials if t.value is not None]
            if not done:
                continue
            steps = [t.number for t in done]
            values = np.array([t.value for t in done])
            tag = f"{name}: " if len(studies) > 1 else ""
            ax.plot(steps, values, "o", ms=3, alpha=0.5, color=f"C{i}", label=f"{tag}trial")
            ax.step(steps, np.minimum.accumulate(values), where="post", lw=1.5, color=f"C{i}",
                    label=f"{tag}best so far ({values.min():.3g} {result.unit})")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("trial number")
        ax.set_ylabel(f"inner validation RMSE [{result.unit}]")
        ax.set_title(f"convergence — {run_name(result.spec)}", fontsize=9)
        ax.legend(fontsize=7)
        out["convergence.png"] = fig
    return out


class SweepRun(Callback):
    """Hydra callback: opens the sweep's parent MLflow run before the jobs start and closes it after.

    The parent's id reaches the jobs (also joblib worker processes) through ``THERMODRIFT_PARENT_RUN_ID``.
    At the end the terminal gets one table of every job (:func:`thermodrift.core.report.runs_table`) and the parent
    run's id; the parent gets a ``grid.csv`` of every child's metrics and the metrics, params and ``best_run_id``
    of the best finished job (:func:`thermodrift.core.report.best_jobs`: by inner validation RMSE, never by held-out
    scores, compared only within a protocol, honest first; a paper-protocol best is tagged ``best_paper_run_id``).
    """

    def on_multirun_start(self, config, **kwargs) -> None:
        exp_id = setup(config.tracking.uri, config.tracking.experiment)
        run = MlflowClient().create_run(exp_id, run_name=f"sweep {os.environ.get('THERMODRIFT_SWEEP_ID', '')}",
                                        tags={"sweep_id": os.environ.get("THERMODRIFT_SWEEP_ID", ""),
                                              "kind": "sweep"})
        os.environ[PARENT_ENV] = run.info.run_id

    def on_multirun_end(self, config, **kwargs) -> None:
        from thermodrift.core import report

        parent = os.environ.pop(PARENT_ENV, None)
        if not parent:
            return
        client = MlflowClient()
        run = client.get_run(parent)
        children = client.search_runs([run.info.experiment_id], f"tags.mlflow.parentRunId = '{parent}'",
                                      order_by=["attributes.start_time ASC"])
        rows = [{**{t: c.data.tags.get(t) for t in TAGS}, **c.data.metrics, "run_id": c.info.run_id,
                 "status": c.info.status} for c in children]
        if rows:
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / "grid.csv"
                pd.DataFrame(rows).to_csv(path, index=False)
                client.log_artifact(parent, str(path))
            try:  # the studies' tables and the grid summary, under report/ on the parent run
                report.log_to_parent(client, parent)
            except Exception as exc:  # a sweep's jobs are done; a table that cannot be built is only noted
                client.set_tag(parent, "report_error", str(exc)[:500])
        ranked = report.best_jobs(children)  # one per protocol, honest first: never compared across protocols
        best = ranked[0] if ranked else None
        for other in ranked[1:]:  # e.g. the best paper-protocol job beside the best honest one
            client.set_tag(parent, f"best_{other.data.tags.get('protocol', '')}_run_id", other.info.run_id)
        if best is not None:
            stamp = int(time.time() * 1000)
            metrics = [Metric(k, v, stamp, 0) for k, v in best.data.metrics.items()
                       if not k.startswith(("trial/", "fold"))]  # trial curves stay in the job's run
            params = [Param(k, v) for k, v in best.data.params.items()]
            for i in range(0, max(len(metrics), len(params)), 100):  # MLflow's batch limits: 1000 / 100
                client.log_batch(parent, metrics=metrics[i:i + 100], params=params[i:i + 100])
            client.set_tag(parent, "best_run_id", best.info.run_id)
            client.set_tag(parent, "best_run_name", best.info.run_name or "")
            client.set_tag(parent, "best_protocol", best.data.tags.get("protocol", ""))
        client.set_terminated(parent)
        failed = sum(c.info.status != "FINISHED" for c in children)
        unit = ", ".join(sorted({c.data.tags.get("unit", "µm") for c in children})) or "µm"
        print(f"\ngrid: {len(children)} jobs{f' ({failed} failed)' if failed else ''}; held-out RMSE ({unit}) "
              "per target, the baselines beside it:\n"
              + report.format_table(report.runs_table(children))
              + "".join(f"\n{line}" for line in report.best_job_lines(ranked))
              + f"\nparent MLflow run {parent} at {config.tracking.uri or DEFAULT_URI}", flush=True)


def held_out(fold_name: str) -> str:
    """A fold's name as the held-out part: ``held out: <name>`` unless the name says so already."""
    return fold_name if "held out" in fold_name else f"held out: {fold_name}"


def _label(result, who: str) -> str:
    """Display name of a prediction source: ``model: <name>`` or the baseline's name."""
    return f"model: {result.spec.model}" if who == "model" else who


def flatten(d: dict, prefix: str = "") -> dict[str, Any]:
    """A nested dict as one level with dotted keys (``{"a": {"b": 1}}`` -> ``{"a.b": 1}``)."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


def _short(v: Any) -> str:
    return str(v)[:500]


# --- the physics verbs: physics computes and returns, the verbs log here -------------------------------------------

def log_calibration(result, mm, out_dir: str | Path, tracking_uri: str | None, run_name: str = "calibrate",
                    experiment: str = "calibrate") -> str:
    """Log a calibration (``CalibrationResult``), its mismatch map (``MismatchMap``: top windows as tags and
    shares), RMSEs (K, µm) and objective, and every file in ``out_dir`` to an MLflow run; returns the run id."""
    setup(tracking_uri, experiment)
    with mlflow.start_run(run_name=run_name) as run:
        mlflow.set_tags({"network": result.network.name, "kind": "calibration"})
        mlflow.log_params({"network": result.network.name, "free_parameters": len(result.estimates),
                           "confidence_level": result.level, "stopped": result.stopped[:250]})
        metrics = {"objective/initial": result.cost_initial, "objective/final": result.cost,
                   "seconds": result.seconds, "unidentifiable": float(len(result.unidentifiable))}
        for c in result.rmse:
            metrics[metric_key("rmse", c)] = result.rmse[c]
            metrics[metric_key("rmse_initial", c)] = result.rmse_initial[c]
        top = mm.by_window().head(5)
        for rank, (name, row) in enumerate(top.iterrows(), start=1):
            metrics[f"mismatch/top{rank}_share"] = float(row["share"])
            mlflow.set_tag(f"mismatch_top{rank}", f"{name} ({row['top_channel']})"[:250])
        mlflow.log_metrics({k: float(v) for k, v in metrics.items() if np.isfinite(v)})
        mlflow.log_artifacts(str(out_dir))
        return run.info.run_id


def log_diagnosis(d, doc: dict[str, Any], out: str | Path, tracking_uri: str | None, run_name: str,
                  seed: int) -> str:
    """Log a diagnosis (``Diagnosis`` and its ``report.json`` document ``doc``): RMSEs (µm), findings with their
    confidence, and every file in ``out`` to an MLflow run; returns the run id."""
    setup(tracking_uri, "diagnose")
    with mlflow.start_run(run_name=run_name) as run:
        mlflow.set_tags({"kind": "diagnosis", "network": d.baseline_network.name,
                         "findings": ",".join(f["mechanism"] for f in d.findings) or "none"})
        mlflow.log_params({"seed": seed, "screened": d.screened, "network": d.baseline_network.name})
        metrics = {"seconds": d.seconds, "findings": float(len(d.findings))}
        for part in ("baseline", "augmented"):
            for key in ("rmse_um", "heldout_rmse_um"):
                for c, v in doc[part][key].items():
                    metrics[metric_key(f"{part}_{key}", c)] = v
        for f in d.findings:
            metrics[f"confidence/{f['mechanism']}"] = f["confidence"]
        mlflow.log_metrics({k: float(v) for k, v in metrics.items() if np.isfinite(v)})
        mlflow.log_artifacts(str(out))
        return run.info.run_id
