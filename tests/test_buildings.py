"""A second thermal domain: building heat inputs as roles, a temperature as the target, and the real houses.

The houses' tables are never shipped; the tests that read them find them as the ``buildings`` dataset does
(``$THERMODRIFT_BUILDINGS``, else ../shared/data/buildings beside the repository) and are skipped without them.
The role and target checks run on a small table written here, in the houses' own format (semicolons, an unnamed
index column, timestamps).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from thermodrift.core.errors import InputError
from thermodrift.core.recording import load_recording
from thermodrift.core.registry import Registry
from thermodrift.core.study import Job, JobSpec, input_columns, model_inputs, targets_of
from thermodrift.plugins.datasets import buildings as plugin

REPO = Path(__file__).parents[1]
DATA = Path(os.environ.get(plugin.ENV_PATH) or REPO.parent / "shared" / "data" / "buildings")
MANIFEST = REPO / "plugins" / "datasets" / "buildings.yaml"
needs_data = pytest.mark.skipif(not (DATA / "blg_1.csv").is_file(), reason=f"building tables not available at {DATA}")


def house_table(path: Path, rows: int = 200, seed: int = 0) -> Path:
    """A one-state house (RC, 15 min) in the published tables' format: ``;``, unnamed index, timestamps."""
    rng = np.random.default_rng(seed)
    t = pd.date_range("2021-11-22 09:00", periods=rows, freq="15min")
    hours = np.arange(rows) * 0.25
    ta = 5 + 4 * np.sin(2 * np.pi * hours / 24) + np.cumsum(rng.normal(0, 0.1, rows))  # weather drifts
    ps = np.clip(0.3 * np.sin(2 * np.pi * (hours - 6) / 24), 0, None) * rng.uniform(0.2, 1.0, rows)  # kW/m²
    thm = np.repeat(60.0 * (rng.random(rows // 8 + 1) < 0.5), 8)[:rows]  # the boiler on or off for 2 h at a time
    ti = np.empty(rows)
    ti[0] = 19.0
    for k in range(1, rows):  # C dTi/dt = (Ta - Ti)/R + a·Ps + b·Thm
        ti[k] = ti[k - 1] + 0.25 * ((ta[k - 1] - ti[k - 1]) / 8.0 + 4.0 * ps[k - 1] + 0.04 * thm[k - 1])
    frame = pd.DataFrame({"t": t.strftime("%Y-%m-%d %H:%M:%S"), "Ps": ps, "Ta": ta, "yTi": ti, "Thm": thm})
    frame.to_csv(path, sep=";")
    return path


def test_heat_input_roles_and_units_load(tmp_path):
    table = house_table(tmp_path / "house.csv")
    rec = load_recording(table, MANIFEST)
    assert {c: (ch.role, ch.unit) for c, ch in rec.channels.items()} == {
        "Ps": ("solar_irradiance", "W_m2"), "Ta": ("ambient", "degC"), "yTi": ("temperature", "degC"),
        "Thm": ("heating", "1")}
    raw = pd.read_csv(table, sep=";")
    assert np.allclose(rec.data["Ps"], 1000.0 * raw["Ps"])  # kW/m² -> W/m²
    assert np.allclose(rec.data["Thm"], raw["Thm"])  # a unitless heating signal is kept as it is
    assert rec.sampling_interval_s == 900.0 and rec.time_s[0] == 0.0  # timestamps -> s from the first row
    manifest = tmp_path / "kw.yaml"  # heating in kW is converted to W; an unquoted unit 1 is the string "1"
    manifest.write_text("time: t\nchannels:\n  Ta: {role: ambient, unit: degC}\n  Thm: {role: heating, unit: kW}\n"
                        "  Ps: {role: solar_irradiance, unit: W/m2}\n  yTi: {role: temperature, unit: degC}\n")
    assert np.allclose(load_recording(table, manifest).data["Thm"], 1000.0 * raw["Thm"])
    manifest.write_text("time: t\nchannels:\n  Thm: {role: heating, unit: 1}\n  yTi: {role: temperature, unit: degC}\n")
    assert load_recording(table, manifest).channels["Thm"].unit == "1"
    manifest.write_text("time: t\nchannels:\n  Ps: {role: solar_irradiance, unit: rpm}\n"
                        "  yTi: {role: temperature, unit: degC}\n")
    with pytest.raises(InputError, match="unit 'rpm' is not valid for role solar_irradiance"):
        load_recording(table, manifest)


def test_a_temperature_target_is_never_an_input_and_an_input_is_never_a_target(tmp_path):
    rec = load_recording(house_table(tmp_path / "house.csv"), MANIFEST)
    targets = targets_of(rec, ["yTi"])
    roles = ("temperature", "ambient", "solar_irradiance", "heating")
    assert input_columns(rec, roles, targets) == ["Ta", "Ps", "Thm"]
    frame = model_inputs(rec, ["Ta"], type("Physics", (), {"extra_input_roles": ("temperature", "ambient")}), targets)
    assert list(frame.columns) == ["Ta"]  # a model that reads every temperature still never reads its target
    with pytest.raises(ValueError, match="never an input"):
        model_inputs(rec, ["Ta", "yTi"], object, targets)
    for wrong, phrase in (("Ta", "role ambient, an input"), ("Thm", "role heating, an input"),
                          ("nope", "not a channel")):
        with pytest.raises(InputError, match=phrase):
            targets_of(rec, [wrong])
    with pytest.raises(InputError, match="no displacement channel.*targets=\\['yTi'\\]"):
        targets_of(rec, None)


def test_a_study_on_a_temperature_target_reports_kelvin(tmp_path):
    rec = load_recording(house_table(tmp_path / "house.csv", rows=300), MANIFEST)
    spec = JobSpec(dataset="house", model="mlr", selector="all", split="chronological", targets=["yTi"],
                   input_roles=("temperature", "ambient", "solar_irradiance", "heating"), n_trials=0,
                   storage=None, progress=False)
    result = Job(spec).run(rec)
    assert result.unit == "K" and result.targets == ["yTi"] and "yTi" not in result.selected
    assert set(result.selected) == {"Ta", "Ps", "Thm"}
    # the house is linear in filtered inputs, not in raw ones: MLR is off, but by a few K, not by µm-sized numbers
    assert 0 < result.summary_metrics("model")["rmse"] < 5


def test_missing_tables_are_one_clear_line(tmp_path):
    registry = Registry()
    plugin.thermodrift_register_datasets(registry)
    with pytest.raises(InputError, match=r"blg_2\.csv not found at the path given") as err:
        registry.create("dataset", "buildings", house=2, path=str(tmp_path))
    assert "\n" not in str(err.value) and plugin.ENV_PATH in str(err.value)
    with pytest.raises(InputError, match="houses 1, 2, 3"):
        registry.create("dataset", "buildings", house=4, path=str(tmp_path))


@needs_data
@pytest.mark.parametrize("house", plugin.HOUSES)
def test_the_issue_manifest_validates_for_every_house(house, tmp_path, cli):
    manifest = tmp_path / "M.yaml"  # as a user writes it, from the issue
    manifest.write_text("time: t\nchannels:\n  Ta: {role: ambient, unit: degC}\n"
                        "  Ps: {role: solar_irradiance, unit: kW/m2}\n  Thm: {role: heating, unit: \"1\"}\n"
                        "  yTi: {role: temperature, unit: degC}\n")
    out = cli(tmp_path, "validate", str(DATA / f"blg_{house}.csv"), "--manifest", str(manifest))
    assert out.returncode == 0, out.stderr
    assert "solar_irradiance (1):" in out.stdout and "heating (1):" in out.stdout and "900 s (regular)" in out.stdout
    rec = Registry()
    plugin.thermodrift_register_datasets(rec)
    recording = rec.create("dataset", "buildings", house=house, path=str(DATA))
    assert len(recording) == (4181 if house == 1 else 6905)
    assert recording.data["Ps"].max() > 200  # W/m² (the table holds kW/m², 0 to 0.4)


@needs_data
@pytest.mark.slow
def test_run_export_compensate_on_a_house_in_kelvin(tmp_path, cli):
    """``thermodrift run dataset=buildings targets=[yTi]`` end to end, then its compensator on the house's rows."""
    out = cli(tmp_path, "run", "dataset=buildings", f"dataset.params.path={DATA}", "targets=[yTi]", "model=mlr",
              "split=chronological", "n_trials=2", "progress=false")
    assert out.returncode == 0, out.stderr[-2000:]
    assert "targets (K): yTi" in out.stdout and "held-out (last 30% of time), K," in out.stdout
    assert "µm" not in out.stdout
    run_id = out.stdout.split("MLflow run ")[1].split()[0]
    refused = cli(tmp_path, "run", "dataset=buildings", f"dataset.params.path={DATA}", "targets=[Ta]", "model=mlr",
                  "split=chronological", "n_trials=0", "progress=false")
    assert refused.returncode == 2 and "target 'Ta' is a channel of role ambient, an input" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1
    out = cli(tmp_path, "export", run_id, "--out", "pkg")
    assert out.returncode == 0, out.stderr[-2000:]
    doc = json.loads((tmp_path / "pkg" / "package.json").read_text())
    assert "yTi" not in doc["model"]["inputs"] and doc["axes"]["yTi"]["unit"] == "degC"
    head = pd.read_csv(DATA / "blg_1.csv", sep=";", index_col=0).iloc[:96]  # one day, as the house wrote it
    head.to_csv(tmp_path / "day.csv", sep=";")
    out = cli(tmp_path, "compensate", "pkg", "--input", "day.csv", "--manifest", str(MANIFEST), "--out", "v.csv",
              "--no-limits")
    assert out.returncode == 0, out.stderr[-2000:]
    values = pd.read_csv(tmp_path / "v.csv")
    assert list(values.columns) == ["time_s", "yTi_degC", "yTi_raw_degC", "yTi_status"]
    assert np.allclose(np.diff(values["time_s"]), 900.0)  # timestamps streamed as seconds
    assert values["yTi_degC"].between(5, 35).all()  # an indoor temperature in °C
    assert "extrapolates" not in out.stderr  # a day of the training part
    head.assign(Ta=head["Ta"] + 30.0).to_csv(tmp_path / "hot.csv", sep=";")  # a heat wave in winter
    out = cli(tmp_path, "compensate", "pkg", "--input", "hot.csv", "--manifest", str(MANIFEST), "--out", "h.csv")
    assert out.returncode == 0, out.stderr[-2000:]
    assert "input row 1: Ta = " in out.stderr and "the model extrapolates" in out.stderr
    assert "the input (96 rows) extrapolates beyond the training range" in out.stderr and "K above" in out.stderr
    refused = cli(tmp_path, "compensate", "pkg", "--input", "day.csv", "--manifest", str(MANIFEST), "--out", "w.csv",
                  "--cnc", "fanuc")
    assert refused.returncode == 2 and "is a temperature: use csv" in refused.stderr


def test_automl_on_a_house_holds_out_the_last_two_weeks_and_scores_by_horizon(tmp_path):
    from thermodrift.core import horizons, splits
    from thermodrift.core.automl import job as automl_job
    from thermodrift.core.automl.search import Settings

    rows = 4 * 24 * 21  # three weeks at 15 min
    rec = load_recording(house_table(tmp_path / "house.csv", rows=rows), MANIFEST)
    (fold,) = splits.make_split("chronological", test_last_h=336).folds(rec)
    assert len(fold.test) == 4 * 24 * 14 and fold.name == "last 336 h" and fold.train[-1] + 1 == fold.test[0]
    with pytest.raises(InputError, match="holds out the whole recording"):
        splits.make_split("chronological", test_last_h=24 * 30).folds(rec)
    spec = JobSpec(dataset="house", model="pipeline", split="chronological", split_params={"test_last_h": 336},
                   targets=["yTi"], input_roles=("temperature", "ambient", "solar_irradiance", "heating"),
                   storage=None, progress=False)
    result = automl_job.run(spec, Settings(budget_fits=8, families=["mlr"], max_folds=2), recording=rec)
    job = result.job
    assert job.unit == "K" and "yTi" not in job.model.feature_names_in_
    table = horizons.scores(job, [0, 24])
    assert list(table.columns) == ["one step (15 min)", "24 h"]
    model = table.loc[f"model: {job.spec.model}"]
    assert model.iloc[0] == model.iloc[1] == pytest.approx(job.summary_metrics("model")["rmse"])  # inputs only
    persistence = table.loc["persistence"]
    assert persistence.iloc[0] == pytest.approx(job.summary_metrics("persistence")["rmse"])
    assert persistence.iloc[1] > 2 * persistence.iloc[0]  # yesterday's temperature is a worse guess than 15 min ago
    assert horizons.steps(0, 900.0) == 1 and horizons.steps(24, 900.0) == 96
    with pytest.raises(InputError, match="horizons_h"):
        horizons.steps(-1, 900.0)
