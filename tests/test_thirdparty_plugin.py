"""An installed outside distribution (tests/thirdparty_plugin: a selector, a model, an optimizer, a CNC format and a
mechanism, one module and one entry-point line each, no YAML) is listed by the CLI, runs end to end
(``group=name``, ``compensate --cnc plc_words``, ``diagnose`` screening ``fan_cooling``) and passes the
conformance suite.

Needs ``pip install --no-deps ./tests/thirdparty_plugin`` in the environment (CI does it).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
from mlflow.tracking import MlflowClient

from thermodrift.testing import tiny_recording
from thermodrift.testing.pytest_components import (CncFormatTests, MechanismTests, ModelTests, OptimizerTests,
                                                   SelectorTests)

PLUGIN = {"selector": ("variance_top_k", "thermodrift_example_plugin.selectors"),
          "model": ("ridge_demo", "thermodrift_example_plugin"),
          "optimizer": ("sobol_demo", "thermodrift_example_plugin.samplers"),
          "cnc": ("plc_words", "thermodrift_example_plugin.controller"),
          "mechanism": ("fan_cooling", "thermodrift_example_plugin.mechanisms")}


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


def test_compensate_writes_the_outside_cnc_format(tmp_path, cli):
    """``compensate --cnc plc_words``: int16 registers in 0.1 µm, the same values the csv format writes in µm."""
    from test_compensator_safety import export, fitted

    model, X, y = fitted("mlr")
    export(model, X, y, tmp_path / "pkg")
    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    values = {}
    for fmt in ("plc_words", "csv"):
        proc = cli(tmp_path, "compensate", "pkg", "--input", "tiny.csv", "--manifest", "tiny.yaml", "--out",
                   f"{fmt}.csv", "--cnc", fmt)
        assert proc.returncode == 0 and f"wrote {fmt} values for" in proc.stdout, proc.stderr
        values[fmt] = pd.read_csv(tmp_path / f"{fmt}.csv")
    words, table = values["plc_words"], values["csv"]
    assert list(words.columns) == ["time_s", "disp_z_um_0.1um", "disp_x_um_0.1um", "disp_z_um_status",
                                   "disp_x_um_status"]
    assert len(words) == len(table) == len(tiny_recording(seed=0).data)
    assert words["disp_z_um_0.1um"].dtype.kind == "i"
    assert np.array_equal(words["disp_z_um_0.1um"], np.round(table["disp_z_um_um"] * 10).astype(int))
    assert (words["disp_x_um_status"] == table["disp_x_um_status"]).all()


def test_diagnose_screens_the_outside_mechanism_and_finds_it_planted(tmp_path, capsys):
    """A recording simulated with a motor fan the baseline network lacks: diagnose, given the outside mechanism
    beside two built-ins, names it first."""
    import yaml

    from thermodrift.core import cli, physics
    from thermodrift.core.physics.diagnose.concealed import concealed_case

    case = concealed_case(physics.load_network("demo_spindle"), "fan_cooling", 3, hours=14.0, dt_s=120.0,
                          magnitude=1.5)
    case.recording.write(tmp_path / "rec.csv", tmp_path / "rec.yaml")
    (tmp_path / "net.yaml").write_text(yaml.safe_dump(physics.network_to_dict(case.baseline)), encoding="utf-8")
    code = cli.main(["diagnose", str(tmp_path / "rec.csv"), "--manifest", str(tmp_path / "rec.yaml"), "--network",
                     str(tmp_path / "net.yaml"), "--out", str(tmp_path / "dx"), "--mechanisms", "fan_cooling",
                     "ambient_coupling", "cutting_heat"])
    assert code == 0, capsys.readouterr().err
    doc = json.loads((tmp_path / "dx" / "report.json").read_text(encoding="utf-8"))
    assert doc["findings"] and doc["findings"][0]["mechanism"] == "fan_cooling"
    assert {r["mechanism"] for r in doc["rejected"]} == {"ambient_coupling", "cutting_heat"}


class TestRidgeDemo(ModelTests):
    """The plugin author's own conformance tests, as its README shows them (the Hydra config included)."""

    name = "ridge_demo"


class TestVarianceTopK(SelectorTests):
    name = "variance_top_k"


class TestSobolDemo(OptimizerTests):
    name = "sobol_demo"


class TestPlcWords(CncFormatTests):
    name = "plc_words"


class TestFanCooling(MechanismTests):
    name = "fan_cooling"
