"""MLflow tracking: a parent run per sweep, a child run per job, trial metrics, figures and the final model.

Tags on every job run: ``dataset``, ``selector``, ``model``, ``optimizer``, ``split``, ``ablation`` (so the
MLflow UI groups and compares them). Metric names: ``test/<metric>`` (mean over displacement channels),
``test/<channel>/<metric>``, ``baseline/<name>/test/<metric>``, ``trial/value`` and ``trial/best`` per trial,
all in µm except R², explained variance, VAF (%), relative error (%) and compensation rate; ``efficiency/train_s``,
``efficiency/latency_batch_ms``, ``efficiency/latency_stream_ms`` (ms per sample) and ``efficiency/n_parameters``.
"""

from __future__ import annotations

import logging
import os
import re
import tempfile
import time
from pathlib import Path
from typing import Any

import mlflow
import mlflow.sklearn
import numpy as np
import optuna
import pandas as pd
from hydra.experimental.callback import Callback
from mlflow.entities import Metric
from mlflow.tracking import MlflowClient

PARENT_ENV = "THERMODRIFT_PARENT_RUN_ID"
DEFAULT_URI = "sqlite:///mlflow.db"
TAGS = ("dataset", "selector", "model", "optimizer", "split", "ablation")


def setup(uri: str | None, experiment: str) -> str:
    """Point MLflow at ``uri`` (default ``sqlite:///mlflow.db``) with telemetry off; return the experiment id."""
    os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
    for name in ("mlflow", "alembic"):  # schema-migration and "creating experiment" chatter
        logging.getLogger(name).setLevel(logging.WARNING)
    logging.getLogger("mlflow.sklearn").setLevel(logging.ERROR)  # the cloudpickle caution: chosen knowingly
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
    """Optuna callback logging each finished trial's value and the running best to the active MLflow run.

    Written here because optuna-integration's MLflowCallback is deprecated in Optuna 5 and opens a run per
    trial; we want trial curves inside the job's run.
    """

    def __init__(self, run_id: str):
        self.run_id = run_id
        self.client = MlflowClient()

    def __call__(self, study: optuna.Study, trial: optuna.trial.FrozenTrial) -> None:
        metrics = {f"trial/{trial.state.name.lower()}": 1.0}
        if trial.state == optuna.trial.TrialState.COMPLETE and trial.value is not None:
            metrics["trial/value"] = float(trial.value)
            metrics["trial/best"] = float(study.best_value)
        stamp = int(time.time() * 1000)
        self.client.log_batch(self.run_id, metrics=[Metric(k, v, stamp, trial.number) for k, v in metrics.items()])


def job_tags(names: dict[str, str], ablation: str, protocol: str) -> dict[str, str]:
    return {**{k: str(names[k]) for k in TAGS if k in names}, "ablation": str(ablation), "protocol": protocol}


def start_job_run(run_name: str, tags: dict[str, str]) -> mlflow.ActiveRun:
    """Start the job's run, nested under the sweep's parent run when there is one."""
    parent = os.environ.get(PARENT_ENV)
    if parent:
        tags = {**tags, "mlflow.parentRunId": parent}
    return mlflow.start_run(run_name=run_name, tags=tags)


def log_result(result, params: dict[str, Any]) -> None:
    """Log a :class:`~thermodrift.core.study.JobResult` into the active run."""
    mlflow.log_params({k: _short(v) for k, v in _flatten(params).items()})
    mlflow.log_param("selected_sensors", ",".join(result.selected))
    trials = result.study.trials if result.study is not None else []  # no study when n_trials=0 (untuned)
    metrics = {"valid/best_rmse": float(result.valid_rmse),
               "study/n_trials": float(len(trials)),
               "study/n_failed": float(sum(t.state == optuna.trial.TrialState.FAIL for t in trials)),
               "study/n_diverged": float(sum(bool(t.user_attrs.get("diverged")) for t in trials))}
    for who in result.folds[0].metrics:
        prefix = ("test",) if who == "model" else ("baseline", who, "test")
        for name, value in result.summary_metrics(who).items():
            metrics[metric_key(*prefix, name)] = value
        if who == "model" and len(result.folds) == 1:
            for channel, per in result.folds[0].metrics[who].items():
                if channel != "mean":
                    metrics.update({metric_key("test", channel, n): v for n, v in per.items()})
    for base in (w for w in result.folds[0].metrics if w != "model"):
        ref = metrics[metric_key("baseline", base, "test", "rmse")]
        if ref > 0:
            metrics[metric_key("skill_vs", base)] = 1.0 - metrics["test/rmse"] / ref
    for key in result.folds[-1].efficiency:  # S3 Table 14: training s, latency ms per sample, parameter count
        metrics[metric_key("efficiency", key)] = float(np.mean([f.efficiency.get(key, np.nan) for f in result.folds]))
    mlflow.log_metrics({k: v for k, v in metrics.items() if np.isfinite(v)})
    mlflow.log_params({f"best/{k}": _short(v) for k, v in result.best_params.items()})
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        comparison(result).to_csv(tmp_path / "comparison.csv")
        mlflow.log_artifact(str(tmp_path / "comparison.csv"))
        for fig_name, fig in figures(result).items():
            fig.savefig(tmp_path / fig_name, dpi=110, bbox_inches="tight")
            mlflow.log_artifact(str(tmp_path / fig_name), artifact_path="figures")
    # Once per job, as an MLflow model (loadable with mlflow.sklearn.load_model). cloudpickle, because skops
    # refuses estimator classes it does not know, and every plugin model is one.
    mlflow.sklearn.log_model(result.model, name="model", serialization_format="cloudpickle",
                             pip_requirements=["thermodrift"])


def comparison(result) -> pd.DataFrame:
    """Held-out metrics (channel mean, averaged over folds) of the model and each baseline, one row each."""
    rows = {_label(result, who): result.summary_metrics(who)
            for who in result.folds[0].metrics}
    return pd.DataFrame(rows).T


def figures(result) -> dict[str, Any]:
    """Prediction vs measurement, residuals and convergence figures. Plain matplotlib Figures, outside pyplot's
    registry, so a grid running many jobs in one process does not pile up open figures."""
    from matplotlib.figure import Figure

    out = {}
    fold = result.folds[-1]
    hours = fold.time_s / 3600.0
    k = fold.y_true.shape[1]
    fig = Figure(figsize=(9, 2.6 * k))
    axes = fig.subplots(k, 1, squeeze=False, sharex=True)
    for i, col in enumerate(fold.y_true.columns):
        ax = axes[i, 0]
        ax.plot(hours, fold.y_true[col].to_numpy(), color="black", lw=1.2, label="measured")
        for who, pred in fold.predictions.items():
            ax.plot(hours, pred[:, i], lw=1, label=_label(result, who),
                    ls="-" if who == "model" else "--")
        ax.set_ylabel(f"{col} [µm]")
        ax.legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel(f"time [h] — {fold.name}")
    out["prediction_vs_measurement.png"] = fig
    fig = Figure(figsize=(9, 2.4 * k))
    axes = fig.subplots(k, 1, squeeze=False, sharex=True)
    for i, col in enumerate(fold.y_true.columns):
        for who, pred in fold.predictions.items():
            axes[i, 0].plot(hours, fold.y_true[col].to_numpy() - pred[:, i], lw=1,
                            label=_label(result, who))
        axes[i, 0].axhline(0, color="grey", lw=0.5)
        axes[i, 0].set_ylabel(f"residual {col} [µm]")
        axes[i, 0].legend(fontsize=7)
    axes[-1, 0].set_xlabel("time [h]")
    out["residuals.png"] = fig
    values = [t.value for t in result.study.trials if t.value is not None] if result.study is not None else []
    if values:
        fig = Figure(figsize=(6, 3.5))
        ax = fig.subplots()
        ax.plot(values, "o", ms=3, alpha=0.6, label="trial")
        ax.plot(np.minimum.accumulate(values), lw=1.5, label="best so far")
        ax.set_xlabel("completed trial")
        ax.set_ylabel("validation RMSE [µm]")
        ax.legend()
        out["convergence.png"] = fig
    return out


class SweepRun(Callback):
    """Hydra callback: opens the sweep's parent MLflow run before the jobs start and closes it after.

    The parent's id reaches the jobs (also joblib worker processes) through ``THERMODRIFT_PARENT_RUN_ID``.
    At the end the parent gets a ``grid.csv`` of every child's held-out metrics.
    """

    def on_multirun_start(self, config, **kwargs) -> None:
        exp_id = setup(config.tracking.uri, config.tracking.experiment)
        run = MlflowClient().create_run(exp_id, run_name=f"sweep {os.environ.get('THERMODRIFT_SWEEP_ID', '')}",
                                        tags={"sweep_id": os.environ.get("THERMODRIFT_SWEEP_ID", ""),
                                              "kind": "sweep"})
        os.environ[PARENT_ENV] = run.info.run_id

    def on_multirun_end(self, config, **kwargs) -> None:
        parent = os.environ.pop(PARENT_ENV, None)
        if not parent:
            return
        client = MlflowClient()
        run = client.get_run(parent)
        children = client.search_runs([run.info.experiment_id], f"tags.mlflow.parentRunId = '{parent}'")
        rows = [{**{t: c.data.tags.get(t) for t in TAGS}, **c.data.metrics, "run_id": c.info.run_id,
                 "status": c.info.status} for c in children]
        if rows:
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / "grid.csv"
                pd.DataFrame(rows).to_csv(path, index=False)
                client.log_artifact(parent, str(path))
        client.set_terminated(parent)


def _label(result, who: str) -> str:
    """Display name of a prediction source: ``model: <name>`` or the baseline's name."""
    return f"model: {result.spec.model}" if who == "model" else who


def _flatten(d: dict, prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


def _short(v: Any) -> str:
    return str(v)[:500]
