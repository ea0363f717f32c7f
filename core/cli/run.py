"""``thermodrift run``: the Hydra app. One job = one (dataset, selector, model, optimizer, split) combination.

Configs come from ``pkg://thermodrift.conf`` plus every search path that plugins add through the
``thermodrift_hydra_searchpaths`` hook (passed as ``hydra.searchpath``, which works in every install mode).
Each invocation gets a unique id (``THERMODRIFT_SWEEP_ID``) used for its output folder and parent MLflow run.
"""

from __future__ import annotations

import datetime
import os
import sys
import uuid

import hydra
import mlflow
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from thermodrift.core import registry, resume, tracking
from thermodrift.core.errors import InputError, PluginError
from thermodrift.core.study import Job, JobSpec

SWEEP_ENV = "THERMODRIFT_SWEEP_ID"
_STATE = {"composed": False}


class Lifecycle(tracking.SweepRun):
    """Hydra callback: notes that the config composed (so a later exit 1 is a job's, not the user's input)
    and opens/closes the sweep's parent MLflow run."""

    def on_run_start(self, config, **kwargs) -> None:
        _STATE["composed"] = True

    def on_multirun_start(self, config, **kwargs) -> None:
        _STATE["composed"] = True
        if config.optuna.storage:  # create the schema once, before parallel jobs race to create it
            Job.storage(config.optuna.storage)
        super().on_multirun_start(config, **kwargs)
        mlflow.MlflowClient().set_tag(os.environ[tracking.PARENT_ENV], resume.OWNER_ATTR, resume.owner())


def spec_from_config(cfg: DictConfig) -> JobSpec:
    """The :class:`JobSpec` of a composed config."""
    c = OmegaConf.to_container(cfg, resolve=True)
    return JobSpec(
        dataset=c["dataset"]["name"], dataset_params=c["dataset"].get("params") or {},
        selector=c["selector"]["name"], selector_params=c["selector"].get("params") or {},
        model=c["model"]["name"], model_params=c["model"].get("params") or {},
        model_search_space=c["model"].get("search_space"),
        optimizer=c["optimizer"]["name"], optimizer_params=c["optimizer"].get("params") or {},
        split=c["split"]["kind"], split_params=c["split"].get("params") or {},
        targets=c.get("targets"), input_roles=tuple(c["input_roles"]), baselines=tuple(c["baselines"]),
        seed=int(c["seed"]), n_trials=int(c["n_trials"]), timeout_s=c["optuna"].get("timeout_s"),
        storage=c["optuna"].get("storage"), study_name=c["optuna"].get("study_name"), progress=bool(c["progress"]),
        threads=int(c["threads"]),
    )


@hydra.main(version_base="1.3", config_path="pkg://thermodrift.conf", config_name="config")
def _task(cfg: DictConfig) -> float | None:
    multirun = HydraConfig.get().mode == RunMode.MULTIRUN
    try:
        spec = spec_from_config(cfg)
    except (InputError, PluginError, KeyError) as exc:
        return _bad_input(exc, multirun)
    tracking.setup(cfg.tracking.uri, cfg.tracking.experiment)
    names = {"dataset": spec.dataset, "selector": spec.selector, "model": spec.model,
             "optimizer": spec.optimizer, "split": spec.split}
    run_name = f"{spec.model} · {spec.optimizer} · {spec.selector} · {spec.dataset} · {spec.split}"
    study_name = spec.study_name or spec.default_study_name()
    tags = {**tracking.job_tags(names, cfg.ablation, "pending"), resume.STUDY_TAG: study_name,
            resume.OWNER_ATTR: resume.owner()}
    with tracking.start_job_run(run_name, tags) as run:
        killed = resume.close_dead_runs(mlflow.MlflowClient(), run.info.experiment_id, study_name)
        if killed:  # this job resumes the study of a killed job
            mlflow.set_tag(resume.RESUMES_TAG, ",".join(killed))
        try:
            result = Job(spec, callbacks=[tracking.TrialLogger(run.info.run_id)]).run()
        except (InputError, PluginError) as exc:
            mlflow.set_tag("error", str(exc)[:5000])
            mlflow.end_run(status="FAILED")
            return _bad_input(exc, multirun)
        mlflow.set_tag("protocol", result.protocol)
        tracking.log_result(result, OmegaConf.to_container(cfg, resolve=True))
    table = tracking.comparison(result)[["rmse", "mae", "max_abs_error", "r2"]]
    print(f"\n{run_name}\nselected sensors: {', '.join(result.selected)}\n"
          f"held-out ({'; '.join(f.name for f in result.folds)}), µm:\n{table.to_string(float_format='%.3f')}\n"
          f"MLflow run {run.info.run_id} at {cfg.tracking.uri}")
    return float(result.study.best_value)


def _bad_input(exc: Exception, multirun: bool) -> None:
    """One line on stderr; a single run exits 2, a grid job is recorded as failed and the grid goes on."""
    print(f"thermodrift: error: {exc}", file=sys.stderr)
    if not multirun:
        raise SystemExit(2)
    return None


# Hydra's options that take a value (`--cfg job`, `-cn name`, ...).
_VALUED = {"--cfg", "-c", "--package", "-p", "--config-path", "-cp", "--config-name", "-cn", "--config-dir", "-cd",
           "--experimental-rerun", "--info", "-i", "--shell-completion", "-sc"}


def _split_flags(args: list[str]) -> tuple[list[str], list[str]]:
    """Hydra's options (with their values) and the overrides. Hydra's argparse reads options only before the
    overrides; users type them anywhere (`thermodrift run model=bp -m`), so they are moved first."""
    flags, rest, i = [], [], 0
    while i < len(args):
        arg = args[i]
        if arg.startswith("-"):
            flags.append(arg)
            if arg in _VALUED and i + 1 < len(args) and not args[i + 1].startswith("-") and "=" not in args[i + 1]:
                flags.append(args[i + 1])
                i += 1
        else:
            rest.append(arg)
        i += 1
    return flags, rest


def main(overrides: list[str]) -> int:
    """Run the Hydra app with command-line ``overrides`` (``-m`` for a multirun grid)."""
    os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
    os.environ.setdefault(SWEEP_ENV, datetime.datetime.now().strftime("%Y-%m-%d_%H-%M-%S_")
                          + uuid.uuid4().hex[:6])
    # Hydra's plugin scan misses our sweeper under a lenient editable install; registering it is idempotent.
    from hydra_plugins.thermodrift_sweeper import register

    register()
    reg = registry.default()
    extra = []
    if reg.searchpaths and not any(o.startswith("hydra.searchpath=") for o in overrides):
        extra = [f"hydra.searchpath=[{','.join(reg.searchpaths)}]"]
    argv = sys.argv
    flags, rest = _split_flags(overrides)
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
