"""An installed outside distribution (tests/thirdparty_plugin: a selector, a model and an optimizer, no YAML)
is listed by the CLI, runs end to end as ``group=name`` and passes the conformance suite.

Needs ``pip install --no-deps ./tests/thirdparty_plugin`` in the environment (CI does it).
"""

from __future__ import annotations

import json

from mlflow.tracking import MlflowClient

from thermodrift.testing import tiny_recording
from thermodrift.testing.pytest_components import ModelTests, OptimizerTests, SelectorTests

PLUGIN = {"selector": ("variance_top_k", "thermodrift_example_plugin.selectors"),
          "model": ("ridge_demo", "thermodrift_example_plugin"),
          "optimizer": ("sobol_demo", "thermodrift_example_plugin.samplers")}


def test_plugins_json_lists_each_component_with_its_distribution(tmp_path, cli):
    proc = cli(tmp_path, "plugins", "--json")
    assert proc.returncode == 0, proc.stderr
    listing = json.loads(proc.stdout)
    for kind, (name, module) in PLUGIN.items():
        found = {c["name"]: c for c in listing["components"][kind]}[name]
        assert (found["origin"], found["module"]) == ("thermodrift-example-plugin", module)
    assert listing["searchpaths"] == [] and listing["failures"] == {}


def test_run_selects_each_yamlless_plugin_component_by_name_and_tracks_it(tmp_path, cli):
    tiny_recording().write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    proc = cli(
        tmp_path, "run", "selector=variance_top_k", "selector.params.k=2", "model=ridge_demo", "optimizer=sobol_demo",
        "n_trials=3", "progress=false",
        "dataset=recording_file", f"dataset.params.table={tmp_path / 'tiny.csv'}",
        f"dataset.params.manifest={tmp_path / 'tiny.yaml'}",
        f"tracking.uri=sqlite:///{tmp_path / 'mlflow.db'}", f"optuna.storage=sqlite:///{tmp_path / 'optuna.db'}",
        f"hydra.run.dir={tmp_path / 'out'}")
    assert proc.returncode == 0, proc.stderr[-3000:]

    client = MlflowClient(tracking_uri=f"sqlite:///{tmp_path / 'mlflow.db'}")
    experiment = client.get_experiment_by_name("thermodrift")
    runs = client.search_runs([experiment.experiment_id], filter_string="tags.model = 'ridge_demo'")
    assert [r.info.status for r in runs] == ["FINISHED"]
    tags = runs[0].data.tags
    assert (tags["selector"], tags["optimizer"]) == ("variance_top_k", "sobol_demo")
    assert "selected sensors: " in proc.stdout
    assert len(proc.stdout.split("selected sensors: ")[1].splitlines()[0].split(", ")) == 2  # k from the override


class TestRidgeDemo(ModelTests):
    """The plugin author's own conformance tests, as its README shows them (the Hydra config included)."""

    name = "ridge_demo"


class TestVarianceTopK(SelectorTests):
    name = "variance_top_k"


class TestSobolDemo(OptimizerTests):
    name = "sobol_demo"
