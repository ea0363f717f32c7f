"""thermodrift diagnose: a concealed mechanism is found, a null case answers none, bad input exits 2 with one
line, and report.json has exactly the shape outside checks read."""

from __future__ import annotations

import json

import numpy as np
import pytest

from thermodrift.core import cli, physics
from thermodrift.core.errors import InputError
from thermodrift.core.physics.diagnose import diagnose
from thermodrift.core.physics.diagnose.concealed import concealed_case
from thermodrift.core.physics.diagnose.windows import driver_windows

# A small library keeps the tests quick; the benchmark screens every registered mechanism.
LIBRARY = ["cutting_heat", "centrifugal_growth", "thermal_tilt", "ambient_coupling", "axis_drive_heat"]


@pytest.fixture(scope="module")
def cutting_case():
    return concealed_case(physics.load_network("demo_spindle"), "cutting_heat", 3, hours=14.0, dt_s=120.0,
                          magnitude=1.5)


def test_a_concealed_cutting_heat_is_found_and_improves_the_held_out_fit(cutting_case):
    d = diagnose(cutting_case.recording, cutting_case.baseline, seed=0, bootstrap=50, only=LIBRARY)
    assert d.findings and d.findings[0]["mechanism"] == "cutting_heat"
    f = d.findings[0]
    truth = cutting_case.params["fraction"]
    found = sum(v for k, v in f["parameters"].items() if k.startswith("fraction"))
    assert found == pytest.approx(truth, rel=0.2)
    final = ~d.fit_rows
    before, after = d.rmse(d.baseline, final), d.rmse(d.augmented, final)
    assert all(after[c] < 0.8 * before[c] for c in before)
    assert 0.5 <= f["confidence"] <= 1.0 and f["where"]


def test_nothing_hidden_answers_none_and_skips_constant_drivers():
    case = concealed_case(physics.load_network("demo_spindle"), None, 4, hours=14.0, dt_s=120.0,
                          constant_drivers=True)
    d = diagnose(case.recording, case.baseline, seed=0, bootstrap=50, only=LIBRARY)
    assert d.findings == []
    reasons = {r["mechanism"]: r["reason"] for r in d.rejected}
    assert "constant" in reasons["cutting_heat"] and "constant" in reasons["axis_drive_heat"]
    assert np.allclose(d.augmented, d.baseline)


def test_windows_come_from_every_driver(cutting_case):
    drivers = {w.driver for w in driver_windows(cutting_case.recording)}
    assert {"speed", "cutting_power", "ambient", "coolant_inlet", "temperature_rate"} <= drivers


def _write(rec, tmp_path, name="rec"):
    table, manifest = tmp_path / f"{name}.csv", tmp_path / f"{name}.yaml"
    rec.write(table, manifest)
    return table, manifest


def test_cli_writes_report_json_in_the_issue_shape(cutting_case, tmp_path):
    table, manifest = _write(cutting_case.recording, tmp_path)
    net = tmp_path / "baseline.yaml"
    import yaml
    net.write_text(yaml.safe_dump(physics.network_to_dict(cutting_case.baseline)), encoding="utf-8")
    out = tmp_path / "dx"
    runs = tmp_path / "mlruns"
    code = cli.main(["diagnose", str(table), "--manifest", str(manifest), "--network", str(net), "--out", str(out),
                     "--tracking-uri", f"sqlite:///{tmp_path / 'mlflow.db'}", "--mechanisms", *LIBRARY])
    assert code == 0
    assert any(p.name == "report.json" for p in runs.rglob("report.json"))  # the MLflow run holds the report
    doc = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert list(doc)[:5] == ["baseline", "findings", "rejected", "augmented", "verdict"]  # keys only added after
    assert doc["adequacy"]["channels"] and set(doc["adequacy"]["channels"]) == set(
        cutting_case.recording.columns("displacement"))
    disp = cutting_case.recording.columns("displacement")
    for part in ("baseline", "augmented"):
        assert list(doc[part]) == ["rmse_um", "heldout_rmse_um"]
        assert all(sorted(doc[part][k]) == sorted(disp) for k in doc[part])
    for f in doc["findings"]:
        assert list(f)[:6] == ["mechanism", "confidence", "parameters", "ci", "where", "evidence"]
        assert 0 <= f["confidence"] <= 1 and isinstance(f["evidence"], str)
        assert f["test"] and f["statistic"] > 0 and 0 < f["fdr_level"] < 1 and f["p_value"] < f["fdr_level"]
        assert f["route"] in ("likelihood ratio, blocks and held-out gain", "decisive held-out gain and blocks")
        assert set(f["ci"]) == set(f["parameters"]) and all(  # truthful: finite and containing the value
            np.isfinite(f["ci"][k]).all() and f["ci"][k][0] <= v <= f["ci"][k][1] for k, v in f["parameters"].items())
        assert not set(f["fixed"]) & set(f["parameters"]) and all(k in f["evidence"] for k in f["fixed"])
        assert all(list(w) == ["channel", "start_s", "end_s"] for w in f["where"])
    assert all(list(r) == ["mechanism", "reason"] for r in doc["rejected"])
    assert doc["findings"][0]["mechanism"] == "cutting_heat" and isinstance(doc["verdict"], str)
    for name in ("report.md", "residuals.csv", "residual_map.png", "fit.png"):
        assert (out / name).stat().st_size > 0


@pytest.mark.parametrize("drop,message", [("displacement", "no displacement channel"), ("speed", "no speed channel"),
                                          ("short", "too short")])
def test_bad_input_exits_2_with_one_line(cutting_case, tmp_path, capsys, drop, message):
    from thermodrift.core.recording import Recording

    rec = cutting_case.recording
    if drop == "short":
        rec = rec.select(np.arange(60))
    else:
        keep = [c for c, ch in rec.channels.items() if ch.role != drop]
        rec = Recording(rec.data[keep], {c: rec.channels[c] for c in keep}, rec.source)
        if drop == "displacement":
            with pytest.raises(InputError, match=message):
                diagnose(rec, cutting_case.baseline)
    table, manifest = _write(rec, tmp_path)
    code = cli.main(["diagnose", str(table), "--manifest", str(manifest), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and message in err and len(err.splitlines()) == 1
