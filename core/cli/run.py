"""``thermodrift run``: the Hydra app. One job = one (dataset, selector, model, optimizer, split) combination.

Configs come from ``pkg://thermodrift.conf`` plus every search path that plugins add through the
``thermodrift_hydra_searchpaths`` hook (passed as ``hydra.searchpath``, which works in every install mode);
every registered component without a YAML gets a config node built from the registry
(:mod:`thermodrift.core.configs`), so ``group=name`` selects any installed component.
Each invocation gets a unique id (``THERMODRIFT_SWEEP_ID``) used for its output folder and parent MLflow run.
"""

from __future__ import annotations

import datetime
import json
import logging
import os
import sys
import time
import uuid
from pathlib import Path
from typing import Callable

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from thermodrift.core import configs, registry, resume, schema, tracking, tracking_faults, trial_faults
from thermodrift.core.automl import extrapolation
from thermodrift.core.cli import error_line, run_options
from thermodrift.core.errors import InputError, PluginError
from thermodrift.core.study import Job, JobSpec, input_columns

SWEEP_ENV = "THERMODRIFT_SWEEP_ID"
_STATE = {"composed": False}
# The job's lines (what it prints, its errors) also go to the files of Hydra's job logging (outputs/<id>/run.log,
# multirun/<id>/<n>/run.log), not to its console handler: the console already has them.
LOG = logging.getLogger("thermodrift.job")
LOG.propagate = False
PROGRESS_EVERY_S = 30.0  # without a terminal, one progress line at most this often


class Lifecycle(tracking.SweepRun):
    """Hydra callback: notes that the config composed (so a later exit 1 is a job's, not the user's input)
    and opens/closes the sweep's parent MLflow run."""

    def on_run_start(self, config, **kwargs) -> None:
        _STATE["composed"] = True

    def on_multirun_end(self, config, **kwargs) -> None:
        parent = os.environ.get(tracking.PARENT_ENV)
        try:
            super().on_multirun_end(config, **kwargs)
            if parent:
                print(sweep_report(tracking.client().get_run(parent), config), flush=True)
        except tracking_faults.failures() as exc:
            jobs = {p.parent.name: json.loads(p.read_text(encoding="utf-8"))
                    for p in Path(config.hydra.sweep.dir).glob("*/job.json")}
            done = sorted((k for k, v in jobs.items() if v["completed"]), key=int)
            print(f"thermodrift: error: the grid ended but the MLflow tracking server at {config.tracking.uri} "
                  f"stopped answering ({' '.join(str(exc).split())[:160]}); jobs completed and logged: "
                  f"{', '.join(done) or 'none'} of {len(jobs)}; every study is kept in {config.optuna.storage} "
                  "(run the same grid again once the server is back)", file=sys.stderr)
            raise SystemExit(2) from None

    def on_multirun_start(self, config, **kwargs) -> None:
        _STATE["composed"] = True
        if config.optuna.storage:  # create the schema once, before parallel jobs race to create it
            Job.storage(config.optuna.storage)
        try:
            tracking_faults.check(config.tracking.uri)
        except InputError as exc:
            print(f"thermodrift: error: {exc}", file=sys.stderr)
            raise SystemExit(2) from None
        with schema.exclusive(config.tracking.uri):
            super().on_multirun_start(config, **kwargs)
        tracking.client().set_tag(os.environ[tracking.PARENT_ENV], resume.OWNER_ATTR, resume.owner())


def sweep_report(parent, config) -> str:
    """The grid's last lines: its sweep id and folder, and where its report was logged (or why it was not)."""
    sweep = parent.data.tags.get("sweep_id") or parent.info.run_id
    lines = [f"sweep {sweep}: job folders in {config.hydra.sweep.dir}"]
    error = parent.data.tags.get("report_error")
    if error:
        lines.append(f"report not built: {error}")
    else:
        lines.append(f"report (report.md, tables as .md and .csv) logged on the parent run: "
                     f"{parent.info.artifact_uri}/report/")
    uri = config.tracking.uri or tracking.DEFAULT_URI
    lines.append(f"write it here: thermodrift report {sweep} --tracking-uri {uri} (into reports/{sweep}/)")
    return "\n".join(lines)


def spec_from_config(cfg: DictConfig) -> JobSpec:
    """The :class:`JobSpec` of a composed config; InputError naming every value the command line must give."""
    unset = OmegaConf.missing_keys(cfg)
    missing = [k for k in tracking.flatten(OmegaConf.to_container(cfg)) if k in unset]  # in config order
    if missing:
        raise InputError(f"{', '.join(missing)} {'has' if len(missing) == 1 else 'have'} no value: add "
                         f"{' '.join(f'{k}=<value>' for k in missing)} to the command")
    c = OmegaConf.to_container(cfg, resolve=True)
    # The top-level ``search_space`` replaces the model's (Hydra merges a dict given to ``model.search_space``).
    space = c["search_space"] if c.get("search_space") is not None else c["model"].get("search_space")
    return JobSpec(
        dataset=c["dataset"]["name"], dataset_params=c["dataset"].get("params") or {},
        selector=c["selector"]["name"], selector_params=c["selector"].get("params") or {},
        selector_search_space=c["selector"].get("search_space"),
        model=c["model"]["name"], model_params=c["model"].get("params") or {},
        model_search_space=space,
        optimizer=c["optimizer"]["name"], optimizer_params=c["optimizer"].get("params") or {},
        split=c["split"]["kind"], split_params=c["split"].get("params") or {},
        targets=c.get("targets"), input_roles=tuple(c["input_roles"]), baselines=tuple(c["baselines"]),
        seed=int(c["seed"]), n_trials=int(c["n_trials"]), timeout_s=c["optuna"].get("timeout_s"),
        pruner=str(c["optuna"].get("pruner") or "median"),
        storage=c["optuna"].get("storage"), study_name=c["optuna"].get("study_name"), progress=bool(c["progress"]),
        threads=int(c["threads"]),
    )


@hydra.main(version_base="1.3", config_path="pkg://thermodrift.conf", config_name="config")
def _task(cfg: DictConfig) -> float | None:
    multirun = HydraConfig.get().mode == RunMode.MULTIRUN
    _log_to_job_files()
    try:
        spec = spec_from_config(cfg)
    except (InputError, PluginError, KeyError) as exc:
        return _bad_input(exc, multirun)
    study_name = spec.study_name or spec.default_study_name()
    trial_faults.log_to(HydraConfig.get().runtime.output_dir)
    try:
        tracking_faults.check(cfg.tracking.uri)
        schema.retrying(lambda: tracking.setup(cfg.tracking.uri, cfg.tracking.experiment), cfg.tracking.uri)
        value = (_automl_job if cfg.get("automl") else _job)(cfg, spec, multirun)
    except InputError as exc:  # the server was down when this job started
        _record_job(study_name, None)
        return _bad_input(exc, multirun)
    except tracking_faults.failures() as exc:
        tracking.drop_active_runs()
        value = _bad_input(tracking_faults.lost(cfg.tracking.uri, study_name, spec.storage, exc), multirun)
    _record_job(study_name, value)
    return value


def _automl_job(cfg: DictConfig, spec: JobSpec, multirun: bool) -> float | None:
    """``thermodrift automl`` (or ``run automl=default``): the search of ``cfg.automl`` for ``spec``'s dataset,
    split and targets, tracked in MLflow."""
    from thermodrift.core.automl import job as automl_job
    from thermodrift.core.automl.search import Settings

    config = OmegaConf.to_container(cfg, resolve=True)
    try:
        settings = Settings(**config["automl"])
    except TypeError as exc:
        return _bad_input(InputError(f"automl: {exc}"), multirun)
    name = spec.study_name or automl_job.study_name(spec, settings)
    dataset = tracking.run_name(spec).split(" · ")[0]
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
            return _bad_input(exc, multirun)
        tracking.log_automl(result, config)
        by_horizon = tracking.log_horizons(result.job, config.get("horizons_h") or [])
    say(automl_report(result, run, cfg.tracking.uri or tracking.DEFAULT_URI, by_horizon))
    return result.job.valid_rmse


def _record_job(study_name: str, value: float | None) -> None:
    """``job.json`` in the job's output folder: whether it completed, so a grid can say what did."""
    folder = Path(HydraConfig.get().runtime.output_dir)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "job.json").write_text(json.dumps({"study": study_name, "completed": value is not None,
                                                 "best_value": value}), encoding="utf-8")


def _job(cfg: DictConfig, spec: JobSpec, multirun: bool) -> float | None:
    names = {"dataset": spec.dataset, "selector": spec.selector, "model": spec.model,
             "optimizer": spec.optimizer, "split": spec.split}
    run_name = tracking.run_name(spec)
    study_name = spec.study_name or spec.default_study_name()
    tags = {**tracking.job_tags(names, cfg.ablation, "pending"), "recording": run_name.split(" · ")[0],
            resume.STUDY_TAG: study_name, resume.OWNER_ATTR: resume.owner()}
    if getattr(registry.get("model", spec.model).factory, "uses_target_history", False):
        tags["reference"] = "reads the measured target"  # not a compensation model: never a grid's best job
    with tracking.start_job_run(run_name, tags) as run:
        killed = resume.close_dead_runs(tracking.client(), run.info.experiment_id, study_name)
        if killed:  # this job resumes the study of a killed job
            tracking.set_tag(resume.RESUMES_TAG, ",".join(killed))
        logger = tracking.TrialLogger(run.info.run_id)
        trial_log = tracking_faults.BufferedCallback(logger)
        job = Job(spec, callbacks=[trial_log], say=say)
        if spec.progress and not sys.stderr.isatty():  # a bar in a file or pipe is one long line: lines instead
            spec.progress = False
            job.callbacks.append(ProgressLines(spec.budget(), lambda: job.unit))
        LOG.info("%s: study %s, MLflow run %s", run_name, study_name, run.info.run_id)
        try:
            result = job.run()
        except (InputError, PluginError) as exc:
            tracking.fail_run(exc)
            return _bad_input(exc, multirun)
        if not trial_log.flush(result.study):
            trial_log.inner(result.study, trial_log.pending[0])  # raises the server's error
        for fold in result.folds:  # a resumed study's stored trials, so the run has every trial's curve
            if fold.study is not None and fold.trials_before:
                logger.replay(fold.study, fold.trials_before)
        tracking.set_tag("protocol", result.protocol)
        tracking.log_result(result, OmegaConf.to_container(cfg, resolve=True))
        by_horizon = tracking.log_horizons(result, list(cfg.get("horizons_h") or []))
    say(job_report(result, run, cfg.tracking.uri or tracking.DEFAULT_URI, by_horizon))
    return result.valid_rmse


def say(text: str) -> None:
    """A line of the job for the console (stdout) and its log file."""
    print(text, flush=True)
    LOG.info(text.strip("\n"))


def _log_to_job_files() -> None:
    """Route :data:`LOG` to the file handlers Hydra's job logging has just set up for this job (none when the
    user turned job logging off), and keep matplotlib's font-cache INFO lines out of them and the console."""
    LOG.handlers = [h for h in logging.getLogger().handlers if isinstance(h, logging.FileHandler)]
    LOG.setLevel(logging.INFO)
    logging.getLogger("matplotlib").setLevel(logging.WARNING)


class ProgressLines:
    """Optuna callback for output that is not a terminal: a line on the finished trials at most every
    :data:`PROGRESS_EVERY_S` s and when the budget is met, on stderr where the bar would be (and in the log)."""

    def __init__(self, n_trials: int, unit: Callable[[], str] = lambda: "µm") -> None:
        self.n_trials = n_trials
        self.unit = unit  # of the RMSE: µm or K, known once the job has its targets
        self.last = -float("inf")

    def __call__(self, study, trial) -> None:
        finished = [t for t in study.get_trials(deepcopy=False) if t.state.is_finished()]
        now = time.monotonic()
        if now - self.last < PROGRESS_EVERY_S and len(finished) < self.n_trials:
            return
        self.last = now
        best = min((t.value for t in finished if t.value is not None), default=None)
        line = (f"{study.study_name}: {len(finished)} of {self.n_trials} trials finished"
                + (f", best inner validation RMSE {best:.3f} {self.unit()}" if best is not None else ""))
        print(line, file=sys.stderr, flush=True)
        LOG.info(line)


def job_report(result, run, uri: str, by_horizon=None) -> str:
    """What a person reads after a job: targets, selection, held-out metrics beside the baselines, what
    persistence is, where the figures are."""
    table = tracking.comparison(result)[["rmse", "mae", "max_abs_error", "r2"]]
    for target in result.targets:
        table[f"rmse {target}"] = [result.summary_metrics(who, target)["rmse"] for who in result.folds[0].metrics]
    params = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in result.best_params.items())
    tuned = ("untuned (n_trials=0), on its defaults" if result.study is None
             else f"tuned{' (last fold)' if len(result.folds) > 1 else ''}: {params or 'nothing to tune'}")
    lines = [f"\n{tracking.run_name(result.spec)}  [{result.protocol} protocol]",
             f"targets ({result.unit}): {', '.join(result.targets)}",
             f"selected sensors{' (last fold)' if len(result.folds) > 1 else ''}: {', '.join(result.selected)}",
             f"model {result.spec.model} {tuned}",
             f"held-out ({'; '.join(f.name.removeprefix('held out: ') for f in result.folds)}), {result.unit}, "
             f"mean over "
             f"{'folds and ' if len(result.folds) > 1 else ''}targets:",
             table.to_string(float_format="%.3f"), *tracking.horizon_lines(by_horizon, result.unit)]
    if "mlr" in result.spec.baselines:
        lines.append(f"mlr baseline: MLR on the {len(result.selected)} selected sensors"
                     f"{' (last fold)' if len(result.folds) > 1 else ''}, the model's inputs")
    same = result.same_as()
    if same:
        lines.append(f"note: the model's held-out predictions equal the {same} baseline's (within 0.001 "
                     f"{result.unit})")
    lines += [f"warning: {line}" for line in extrapolation.of_result(result)]
    names = dict.fromkeys(result.spec.model if who == "model" else who for who in result.folds[0].metrics)
    for name in (n for n in names if getattr(registry.get("model", n).factory, "uses_target_history", False)):
        lines.append(f"{name} reads the measured target of the previous sample: a reference, not a compensation "
                     "model")
    lines.append(f"figures: {run.info.artifact_uri}/{tracking.FIGURES}/")
    lines.append(f"MLflow run {run.info.run_id} at {uri}")
    return "\n".join(lines)


def automl_report(result, run, uri: str, by_horizon=None) -> str:
    """What a person reads after the search: the leaderboard's top, the choice, held-out metrics beside the
    baselines, the parent run."""
    job = result.job
    board = result.leaderboard
    show = board[["rank", "trial", "model", "settings", "selector", "features", "status", "inner_score"]
                 + [c for c in board.columns if c.startswith("fold")]
                 + (["never_extrapolated"] if result.extrapolation else [])].head(10)
    table = tracking.comparison(job)[["rmse", "mae", "max_abs_error", "r2"]]
    for target in job.targets:
        table[f"rmse {target}"] = [job.summary_metrics(who, target)["rmse"] for who in job.folds[0].metrics]
    inputs = input_columns(job.recording, job.spec.input_roles, job.targets)
    lines = [f"\nautoml on {job.spec.dataset} · {job.spec.split}  [{job.protocol} protocol]",
             f"targets ({job.unit}): {', '.join(job.targets)}",
             f"inner folds: {'; '.join(f.name for f in result.search.folds)}",
             f"{len(board)} candidates, {result.search.fits} fits, {int((board['status'] == 'failed').sum())} "
             f"failed, stopped by {result.search.stopped_by}, {result.wall_s:.0f} s; leaderboard (inner RMSE {job.unit}):",
             show.to_string(index=False, float_format=lambda v: f"{v:.3f}"),
             f"chosen ({job.spec.model}, inner score {job.valid_rmse:.3f} {job.unit}): {result.describe()}",
             f"held-out ({job.folds[0].name.removeprefix('held out: ')}), {job.unit}, mean over targets:",
             table.to_string(float_format="%.3f"),
             *tracking.horizon_lines(by_horizon, job.unit),
             *([f"warning: {result.extrapolates()}; candidates with never_extrapolated=True were never validated "
                "beyond a fold's training range in the drivers they read"] if result.extrapolation else []),
             *([f"mlr baseline: MLR on every input temperature ({len(inputs)}), as in every automl job"]
               if "mlr" in job.spec.baselines else []),
             f"leaderboard: {run.info.artifact_uri}/leaderboard.csv",
             f"MLflow run {run.info.run_id} at {uri}"]
    return "\n".join(lines)


def _bad_input(exc: Exception, multirun: bool) -> None:
    """One line on stderr (and in the job's log); a single run exits 2, a grid job is recorded as failed and the
    grid goes on."""
    error_line(f"thermodrift: error: {exc}")
    LOG.error("%s", exc)
    if not multirun:
        raise SystemExit(2)
    return None


def main(overrides: list[str]) -> int:
    """Run the Hydra app with command-line ``overrides`` (``-m`` for a multirun grid)."""
    os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
    os.environ.setdefault(SWEEP_ENV, datetime.datetime.now().strftime("%Y-%m-%d_%H-%M-%S_")
                          + uuid.uuid4().hex[:6])
    reg = registry.default()
    flags, rest = run_options.split_flags(overrides)
    run_options.check_overrides(rest, reg)  # with the plugins loaded: a component's parameter names too
    for register in reg.hydra_plugins:  # e.g. the thermodrift sweeper; registering is idempotent
        register()
    for plugin, error in reg.failures.items():  # `thermodrift plugins` lists them too
        print(f"thermodrift: warning: plugin {plugin} failed to load and is left out: {error}", file=sys.stderr)
    configs.store(reg)
    extra = []
    if reg.searchpaths and not any(o.startswith("hydra.searchpath=") for o in overrides):
        extra = [f"hydra.searchpath=[{','.join(reg.searchpaths)}]"]
    argv = sys.argv
    sys.argv = ["thermodrift run", *flags, *rest, *extra]
    try:
        _task()
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        # Hydra exits 1 when the overrides do not compose (a wrong group option, a typo): that is bad input.
        return 2 if code == 1 and not _STATE["composed"] else code
    finally:
        sys.argv = argv
    return 0
