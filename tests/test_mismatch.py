"""Mismatch map: schedule windows, ranking a concealed effect first, figures, MLflow logging."""

import json
from pathlib import Path

import mlflow
import numpy as np
import pytest

from thermodrift.core import physics
from thermodrift.core.physics import calibration as cal
from thermodrift.core.tracking import log_calibration
from thermodrift.core.physics import mismatch, scenarios
from thermodrift.core.physics.scenarios import Block
from thermodrift.core.physics.synthetic import synthesize

SPEC = Path(__file__).parent / "data" / "two_node_network.yaml"  # two measured nodes, one displacement
PROGRAMME = [Block(0.25), Block(2, 3000), Block(1.5), Block(2, 6000), Block(1.5)]


def test_schedule_windows_cut_steps_runs_and_stops():
    scen = scenarios.blocks(PROGRAMME, 60.0)
    windows = mismatch.schedule_windows(scen.time_s, scen.frame["speed_rpm"].to_numpy(), step_s=900.0)
    assert [w.kind for w in windows] == ["stopped", "step", "running", "step", "stopped", "step", "running",
                                         "step", "stopped"]
    assert windows[1].name == "step 0→3000 rpm at 0.25 h"
    assert windows[2].start_s - windows[1].start_s == pytest.approx(900.0)
    # windows tile the recording without gaps or overlaps
    assert all(a.end_s == b.start_s for a, b in zip(windows, windows[1:]))
    assert windows[0].start_s == 0.0 and windows[-1].end_s == pytest.approx(scen.time_s[-1] + 60.0)


@pytest.fixture(scope="module")
def concealed():
    """Calibrate the true network to a recording with a concealed +1 µm drift during the second stop."""
    truth = physics.load_network(SPEC)
    rec = synthesize(truth, scenarios.blocks(PROGRAMME, 60.0), 1).recording
    h = rec.time_s / 3600.0
    hidden = h >= 6.0  # the stop after 6000 rpm (5.75–7.25 h) after its step window: nothing changes there
    rec.data.loc[hidden, "disp_z"] += 1.0
    result = cal.calibrate(rec, truth.with_values({"edges.a-b.G_W_K": 4.0}),
                           free=["edges.*.G_W_K", "sources.heat.viscous_W"])
    return result, mismatch.mismatch_map(result)


def test_concealed_effect_window_is_ranked_first(concealed):
    result, mm = concealed
    ranked = mm.by_window()
    # calibration bends the network towards the offset (the never-worse guard keeps the displacement fit at
    # least as good as the start's, which absorbed part of it), so the window shares the top with one other
    assert "stop from 6.00 h" in ranked.index[:2]
    window = ranked.loc["stop from 6.00 h"]
    assert window["top_channel"] == "disp_z"
    assert window["share"] > 1.2 * ranked.iloc[2]["share"]
    assert window["excess"] > 1.5  # more than its share of the time
    assert mm.by_channel().index[0] == "disp_z"
    cell = mm.cells[(mm.cells["window"] == "stop from 6.00 h") & (mm.cells["channel"] == "disp_z")].iloc[0]
    assert cell["mean"] > 0.15  # the injected sign, in µm (part of the 1 µm is absorbed)
    assert mm.cells["share"].sum() == pytest.approx(1.0)


def test_mismatch_outputs_json_and_figures(concealed, tmp_path):
    result, mm = concealed
    doc = mm.to_dict()
    assert json.loads(json.dumps(doc))["ranked_windows"][0]["window"] == mm.by_window().index[0]
    heat = mismatch.plot_heatmap(mm, tmp_path / "mismatch_heatmap.png", speed=(result.time_s, result.speed_rpm))
    before = mismatch.plot_before_after(result, tmp_path / "before_after.png", mm)
    for path in (heat, before):
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000


def test_mismatch_is_logged_to_mlflow(concealed, tmp_path):
    result, mm = concealed
    out = tmp_path / "out"
    out.mkdir()
    (out / "mismatch.json").write_text(json.dumps(mm.to_dict()), encoding="utf-8")
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    run_id = log_calibration(result, mm, out, uri, run_name="test")
    run = mlflow.MlflowClient(uri).get_run(run_id)
    assert run.data.metrics["rmse/disp_z"] == pytest.approx(result.rmse["disp_z"])
    assert run.data.tags["mismatch_top1"].startswith(mm.by_window().index[0])
    assert [a.path for a in mlflow.MlflowClient(uri).list_artifacts(run_id)] == ["mismatch.json"]
    assert np.isfinite(run.data.metrics["objective/final"])
