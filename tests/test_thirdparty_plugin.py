"""An installed outside distribution (tests/thirdparty_plugin) is listed by the CLI and runs end to end.

Needs ``pip install --no-deps ./tests/thirdparty_plugin`` in the environment (CI does it).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from mlflow.tracking import MlflowClient

from thermodrift.testing import tiny_recording
from thermodrift.testing.pytest_components import ModelTests

THERMODRIFT = [sys.executable, "-m", "thermodrift.core.cli"]


def _thermodrift(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true"}
    return subprocess.run([*THERMODRIFT, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_plugins_json_lists_the_model_with_its_distribution(tmp_path):
    proc = _thermodrift("plugins", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    listing = json.loads(proc.stdout)
    models = {m["name"]: m for m in listing["components"]["model"]}
    assert models["ridge_demo"]["origin"] == "thermodrift-example-plugin"
    assert models["ridge_demo"]["module"] == "thermodrift_example_plugin"
    assert "pkg://thermodrift_example_plugin.conf" in listing["searchpaths"]


def test_run_with_the_plugin_model_finishes_and_is_tracked(tmp_path):
    tiny_recording().write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    proc = _thermodrift(
        "run", "model=ridge_demo", "optimizer=random", "selector=all", "n_trials=3", "progress=false",
        "dataset=recording_file", f"dataset.params.table={tmp_path / 'tiny.csv'}",
        f"dataset.params.manifest={tmp_path / 'tiny.yaml'}",
        f"tracking.uri=sqlite:///{tmp_path / 'mlflow.db'}", f"optuna.storage=sqlite:///{tmp_path / 'optuna.db'}",
        f"hydra.run.dir={tmp_path / 'out'}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]

    client = MlflowClient(tracking_uri=f"sqlite:///{tmp_path / 'mlflow.db'}")
    experiment = client.get_experiment_by_name("thermodrift")
    runs = client.search_runs([experiment.experiment_id], filter_string="tags.model = 'ridge_demo'")
    assert [r.info.status for r in runs] == ["FINISHED"]
    assert runs[0].data.tags["optimizer"] == "random"


class TestRidgeDemo(ModelTests):
    """The plugin author's own conformance test, as its README shows it."""

    name = "ridge_demo"
