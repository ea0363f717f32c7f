"""``thermodrift automl [overrides]``: ``thermodrift run automl=default [overrides]``, the search across families.

The same Hydra config groups, overrides, checks and did-you-mean answers as ``run`` (dataset, split, targets,
seed, tracking, optuna.storage, progress); the model, selector and optimizer groups are not used: the search
chooses. Settings are ``automl.<key>=<value>`` (``conf/automl/default.yaml``). In MLflow: one run tagged
``kind=automl`` (held-out metrics as ``run`` logs them, ``leaderboard.csv`` and ``leaderboard.md`` at the artifact
root, the chosen pipeline's parameters, the pipeline as ``model``), with one child run per family tried, tagged
``kind=automl_candidate``. This module imports nothing heavy until a job runs, so ``--help`` answers fast.
"""

from __future__ import annotations

import sys
from pathlib import Path

USAGE = """usage: thermodrift automl [KEY=VALUE ...] [GROUP=OPTION ...] [automl.KEY=VALUE ...]

Searches selector (with its settings, or all sensors) x input features (raw, or filtered temperatures and drive
heat terms) x model family (every registered model, plugins included) x the family's settings. Inner validation
predicts each later working condition of the training part from the earlier ones; the best pipeline (or a greedy
ensemble, when it is better there) is refitted on the training part and scored once on the held-out part beside
persistence and MLR, in MLflow (a run tagged kind=automl with leaderboard.csv). Budget: automl.budget_fits
(deterministic; default 120) or also automl.timeout_s (s, load-dependent). A re-run with the same storage resumes.

examples:
  thermodrift automl dataset=fl_thermal split=time_window split.params.train_end_h=24.13 \\
      split.params.test_start_h=24.13 split.params.test_end_h=32.13 "targets=['ch3(um)']"
  thermodrift automl experiment=fl_thermal_5000rpm_heldout automl.budget_fits=60
  thermodrift automl dataset=recording_file dataset.params.table=my.csv dataset.params.manifest=my.yaml
  thermodrift automl "automl.families=[mlr,transfer_function,lptn_hybrid]" seed=1

automl settings (automl.KEY=VALUE):"""


def help_text() -> str:
    """``thermodrift automl --help``: its usage, its settings, then the groups and keys it shares with ``run``."""
    from importlib import resources

    from thermodrift.core.cli import run_options

    lines = [USAGE]
    text = resources.files("thermodrift.conf.automl").joinpath("default.yaml").read_text(encoding="utf-8")
    for line in text.splitlines():
        if line and not line.startswith("#"):
            key, _, rest = line.partition(":")
            value, _, doc = rest.partition("#")
            lines.append(f"  {key:<16}{value.strip():<10} {doc.strip()}")
    shared = run_options.help_text().split("\n\n", 3)[-1]
    return "\n".join(lines) + "\n\nshared with thermodrift run:\n" + shared


def as_run(args: list[str]) -> list[str]:
    """The ``run`` command line of ``automl args``: ``automl=default`` first unless an automl option is given."""
    given = any(a.startswith(("automl=", "experiment=automl")) for a in args)
    return list(args) if given else ["automl=default", *args]


def job(cfg, spec, multirun: bool, bad_input) -> float | None:
    """Run the search of ``cfg.automl`` for ``spec``'s dataset, split and targets, tracked in MLflow."""
    from omegaconf import OmegaConf

    from thermodrift.core import resume, tracking
    from thermodrift.core.automl import job as automl_job
    from thermodrift.core.automl.search import Settings
    from thermodrift.core.cli import error_line
    from thermodrift.core.errors import InputError, PluginError

    config = OmegaConf.to_container(cfg, resolve=True)
    try:
        settings = Settings(**config["automl"])
    except TypeError as exc:
        return bad_input(InputError(f"automl: {exc}"), multirun)
    name = spec.study_name or automl_job.study_name(spec, settings)
    table = (spec.dataset_params or {}).get("table")
    dataset = Path(str(table)).name if table else spec.dataset
    tags = {"kind": "automl", "dataset": spec.dataset, "split": spec.split, "ablation": str(config.get("ablation")),
            "model": "pending", "protocol": "pending", "recording": dataset, resume.STUDY_TAG: name,
            resume.OWNER_ATTR: resume.owner()}
    if spec.progress and not sys.stderr.isatty():  # a bar redrawn in a file or a pipe is one long line
        spec.progress = False
    with tracking.start_job_run(f"{dataset} · automl · {spec.split}", tags) as run:
        try:
            result = automl_job.run(spec, settings, say=error_line)
        except (InputError, PluginError) as exc:
            tracking.fail_run(exc)
            return bad_input(exc, multirun)
        tracking.log_automl(result, config, _describe(result))
        by_horizon = tracking.log_horizons(result.job, config.get("horizons_h") or [])
    print(report(result, run, cfg.tracking.uri or tracking.DEFAULT_URI, by_horizon), flush=True)
    return result.job.valid_rmse


def _describe(result) -> str:
    from thermodrift.core.automl import space

    ens = result.search.ensemble
    if ens is None:
        return space.describe(result.search.best.candidate.params)
    return " + ".join(f"{w:.2f} × [{space.describe(m)}]" for w, m in zip(ens["weights"], ens["members"]))


def _inputs(job) -> list[str]:
    """The candidate input temperatures of an automl job (what its baselines read)."""
    return [c for role in job.spec.input_roles for c in job.recording.columns(role)]


def report(result, run, uri: str, by_horizon=None) -> str:
    """What a person reads after the search: the leaderboard's top, the choice, held-out metrics beside the
    baselines, the parent run."""
    from thermodrift.core import tracking

    job = result.job
    board = result.leaderboard
    show = board[["rank", "trial", "model", "settings", "selector", "features", "status", "inner_score"]
                 + [c for c in board.columns if c.startswith("fold")]].head(10)
    table = tracking.comparison(job)[["rmse", "mae", "max_abs_error", "r2"]]
    for target in job.targets:
        table[f"rmse {target}"] = [job.summary_metrics(who, target)["rmse"] for who in job.folds[0].metrics]
    lines = [f"\nautoml on {job.spec.dataset} · {job.spec.split}  [{job.protocol} protocol]",
             f"targets ({job.unit}): {', '.join(job.targets)}",
             f"inner folds: {'; '.join(f.name for f in result.search.folds)}",
             f"{len(board)} candidates, {result.search.fits} fits, {int((board['status'] == 'failed').sum())} "
             f"failed, stopped by {result.search.stopped_by}, {result.wall_s:.0f} s; leaderboard (inner RMSE {job.unit}):",
             show.to_string(index=False, float_format=lambda v: f"{v:.3f}"),
             f"chosen ({job.spec.model}, inner score {job.valid_rmse:.3f} {job.unit}): {_describe(result)}",
             f"held-out ({job.folds[0].name}), {job.unit}, mean over targets:",
             table.to_string(float_format="%.3f"),
             *tracking.horizon_lines(by_horizon, job.unit),
             *([f"mlr baseline: MLR on every input temperature ({len(_inputs(job))}), as in every automl job"]
               if "mlr" in job.spec.baselines else []),
             f"leaderboard: {run.info.artifact_uri}/leaderboard.csv",
             f"MLflow run {run.info.run_id} at {uri}"]
    return "\n".join(lines)
