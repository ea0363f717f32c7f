"""`thermodrift export` on a real logged run, then `thermodrift compensate` as a controller-side user runs it."""

import json

import mlflow
import mlflow.pyfunc
import numpy as np
import pandas as pd
import pytest

from thermodrift.testing.data import tiny_recording

pytestmark = pytest.mark.slow  # one real `thermodrift run` (~40 s on a busy runner) shared by the module


@pytest.fixture(scope="module")
def exported(tmp_path_factory, cli):
    """A tiny untuned transfer_function run (filters: a model with state), exported."""
    cwd = tmp_path_factory.mktemp("run")
    tiny_recording(seed=0).write(cwd / "tiny.csv", cwd / "tiny.yaml")
    out = cli(cwd, "run", "dataset=recording_file", "dataset.params.table=tiny.csv",
              "dataset.params.manifest=tiny.yaml", "progress=false", "model=transfer_function",
              "n_trials=0", "selector=all")
    assert out.returncode == 0, out.stderr[-2000:]
    run_id = out.stdout.split("MLflow run ")[1].split()[0]
    assert f"MLflow run {run_id} at sqlite:///mlflow.db" in out.stdout
    out = cli(cwd, "export", run_id, "--out", "pkg")
    assert out.returncode == 0, out.stderr[-2000:]
    return cwd, run_id


def test_export_logs_the_package_and_the_model_still_loads(exported):
    cwd, run_id = exported
    doc = json.loads((cwd / "pkg" / "package.json").read_text())
    assert doc["model"]["runtime"] == "transfer_function" and doc["source"]["run_id"] == run_id
    assert doc["sampling_interval_s"] == 60.0 and set(doc["limits"]["inputs"]) == set(doc["model"]["inputs"])
    assert set(doc["fallbacks"]) == set(doc["model"]["inputs"])  # a cheap family: one per input
    assert doc["axes"]["disp_z_um"]["axis"] == "z"
    mlflow.set_tracking_uri(f"sqlite:///{cwd / 'mlflow.db'}")
    client = mlflow.MlflowClient()
    assert {"compensator/package.json", "compensator/arrays.npz"} <= {
        a.path for a in client.list_artifacts(run_id, "compensator")}
    assert {"limits.json", "fallbacks"} <= {a.path for a in client.list_artifacts(run_id)}
    model = mlflow.pyfunc.load_model(f"runs:/{run_id}/model")
    X = tiny_recording(seed=0).data[doc["model"]["inputs"]]
    assert model.predict(X).shape == (len(X), 2)


def test_no_limits_replay_equals_predict_with_history_and_stdin_streams(exported, cli):
    cwd, run_id = exported
    out = cli(cwd, "compensate", "pkg", "--input", "tiny.csv", "--manifest", "tiny.yaml", "--out", "v.csv",
              "--no-limits")
    assert out.returncode == 0, out.stderr[-2000:]
    values = pd.read_csv(cwd / "v.csv")
    assert list(values.columns[:4]) == ["time_s", "disp_z_um_um", "disp_z_um_raw_um", "disp_z_um_status"]
    mlflow.set_tracking_uri(f"sqlite:///{cwd / 'mlflow.db'}")
    model = mlflow.pyfunc.load_model(f"runs:/{run_id}/model")
    doc = json.loads((cwd / "pkg" / "package.json").read_text())
    rec = tiny_recording(seed=0)
    X = rec.data[doc["model"]["inputs"]]
    X.attrs["roles"] = {c: rec.channels[c].role for c in X.columns}
    expected = model.predict(X)  # the whole recording from its first row: history empty
    assert np.abs(values[["disp_z_um_um", "disp_x_um_um"]].to_numpy() - expected).max() <= 1e-9
    piped = cli(cwd, "compensate", "pkg", "--input", "-", "--manifest", "tiny.yaml", "--out", "-",
                "--no-limits", stdin=(cwd / "tiny.csv").read_text())
    assert piped.returncode == 0 and piped.stdout.replace("\r\n", "\n") == (cwd / "v.csv").read_text()


def test_an_empty_cell_is_a_fault_of_its_row_not_a_stop(exported, cli):
    cwd, _ = exported
    table = pd.read_csv(cwd / "tiny.csv")
    table.loc[20, "T_column"] = np.nan
    table.to_csv(cwd / "holes.csv", index=False)
    out = cli(cwd, "compensate", "pkg", "--input", "holes.csv", "--manifest", "tiny.yaml", "--out",
              "h.csv", "--audit", "a.jsonl", "--cnc", "fanuc")
    assert out.returncode == 0, out.stderr[-2000:]
    values = pd.read_csv(cwd / "h.csv")
    assert len(values) >= len(table) and values.loc[20, "disp_z_um_status"] == "fallback"
    lines = [json.loads(x) for x in (cwd / "a.jsonl").read_text().splitlines()]
    assert {"sensor": "T_column", "reason": "missing"} in lines[20]["reasons"]
    assert lines[20]["inputs"]["T_column"] is None


@pytest.mark.parametrize("change, needle", [
    ("drop_column", "column 'T_column': column not found in the input header"),
    ("unknown_unit", "unknown unit 'furlong'"),
    ("manifest_without_input", "the manifest does not name an input of the package"),
    ("bad_package", "not a usable compensator package"),
    ("unknown_run", "no MLflow run"),
])
def test_bad_input_is_one_line_and_exit_2(exported, change, needle, cli):
    cwd, _ = exported
    table, manifest, package = "tiny.csv", "tiny.yaml", "pkg"
    text = (cwd / "tiny.yaml").read_text()
    if change == "drop_column":
        pd.read_csv(cwd / "tiny.csv").drop(columns=["T_column"]).to_csv(cwd / "cut.csv", index=False)
        table = "cut.csv"
    elif change == "unknown_unit":
        (cwd / "m.yaml").write_text(text.replace("T_column: {role: temperature, unit: degC",
                                                 "T_column: {role: temperature, unit: furlong"))
        manifest = "m.yaml"
    elif change == "manifest_without_input":
        (cwd / "m.yaml").write_text("\n".join(line for line in text.splitlines() if "T_column" not in line))
        manifest = "m.yaml"
    elif change == "bad_package":
        package = "tiny.yaml"
    if change == "unknown_run":
        out = cli(cwd, "export", "0123456789abcdef", "--out", "x")
    else:
        out = cli(cwd, "compensate", package, "--input", table, "--manifest", manifest, "--out", "o.csv")
    assert out.returncode == 2 and needle in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and "Traceback" not in out.stderr
