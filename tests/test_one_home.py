"""One home per concept: the default tracking store, the shared CLI options, the metrics, the seeding and the
MLflow calls each live in one module. Read from the source, so nothing needs importing."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import yaml

REPO = Path(__file__).parents[1]
PACKAGE = ("core", "plugins", "compensator")


def _sources(*folders: str) -> dict[str, str]:
    return {str(p.relative_to(REPO)): p.read_text(encoding="utf-8")
            for folder in folders for p in sorted((REPO / folder).rglob("*.py"))}


def test_the_default_tracking_store_is_named_in_one_module_and_the_config_agrees():
    from thermodrift.core.tracking_faults import DEFAULT_URI

    homes = [path for path, text in _sources(*PACKAGE).items() if "sqlite:///mlflow.db" in text]
    assert homes == ["core/tracking_faults.py"]
    config = yaml.safe_load((REPO / "conf" / "config.yaml").read_text(encoding="utf-8"))
    assert config["tracking"]["uri"] == DEFAULT_URI


def test_out_and_tracking_uri_are_defined_once_for_every_verb():
    homes = {path for path, text in _sources("core/cli").items()
             if re.search(r"""add_argument\(\s*["']--(out|tracking-uri)["']""", text)}
    assert homes == {"core/cli/options.py"}


# A root mean square written out: sqrt over a mean (numpy), the torch trainer's on tensors excepted.
_RMS = re.compile(r"sqrt\(\s*\(*[^()]*(\([^()]*\)[^()]*)*\*\*\s*2\)*\.mean\(|sqrt\(\s*np\.(nan)?mean\(")


def test_root_mean_squares_are_computed_only_by_core_metrics():
    homes = {path for path, text in _sources(*PACKAGE, "benchmarks").items() if _RMS.search(text)}
    assert homes == {"core/metrics.py"}


def test_a_component_gets_its_seed_only_through_registry_with_seed():
    """``registry.with_seed`` knows whether a component takes ``random_state`` or ``seed``; nobody else sets it."""
    seeding = re.compile(r"""setdefault\(\s*["'](random_state|seed)["']|["']random_state["']\s*:\s*(?!None)[A-Za-z_]""")
    homes = {path for path, text in _sources(*PACKAGE).items() if seeding.search(text)}
    assert homes == set()


def test_mlflow_is_called_from_tracking_only_among_the_job_the_cli_and_deployment():
    """The job's verbs and the export parts reach MLflow through :mod:`thermodrift.core.tracking`."""
    calls = re.compile(r"\bmlflow\.\w|MlflowClient|^\s*import mlflow|^\s*from mlflow", re.M)
    homes = {path for path, text in _sources("core/cli", "core/automl").items() if calls.search(text)}
    homes |= {p for p in ["core/deployment.py", "core/study.py"] if calls.search((REPO / p).read_text(encoding="utf-8"))}
    assert homes == set()
