"""AutoML says when it extrapolates: the held-out part (or a compensator's input) beyond a driver's training range
by more than the stated margin is named with how far, and the leaderboard marks candidates whose inner folds never
extrapolated in those drivers."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from thermodrift.core import registry, splits
from thermodrift.core.automl import extrapolation as ex, job
from thermodrift.core.automl.search import Settings
from thermodrift.core.physics import scenarios
from thermodrift.core.physics.scenarios import Block
from thermodrift.core.physics.spec import load_network
from thermodrift.core.physics.synthetic import synthesize
from thermodrift.core.recording import Channel, Recording
from thermodrift.core.study import JobSpec

REPO = Path(__file__).parents[1]
WORKBOOK = Path(os.environ.get("THERMODRIFT_FL_THERMAL") or REPO.parent / "shared" / "data" / "fl_thermal" / "data.xlsx")


def test_the_margin_is_stated_per_role_with_a_sensor_floor():
    assert ex.margin("speed", 0.0, 1600.0) == pytest.approx(160.0)  # 10 % of the speed span
    assert ex.margin("cutting_power", 0.0, 1000.0) == pytest.approx(210.0)  # the same in heat: 1.1² − 1
    assert ex.margin("temperature", 20.0, 40.0) == pytest.approx(4.2)
    assert ex.margin("ambient", 20.0, 21.0) == 0.5  # a Pt100's accuracy, not a share of a small span
    train = pd.DataFrame({"n": [0.0, 1000.0], "T": [20.0, 21.0], "y": [0.0, 1.0]})
    roles = {"n": "speed", "T": "temperature", "y": "displacement"}
    inside = pd.DataFrame({"n": [1090.0, -50.0], "T": [21.45, 19.6], "y": [50.0, 50.0]})
    assert ex.excursions(train, inside, roles) == []  # within the margins; a target is no driver
    beyond = pd.DataFrame({"n": [1150.0, 1200.0, 900.0], "T": [21.0, 20.0, 22.0], "y": [0.0, 0.0, 0.0]})
    found = ex.excursions(train, beyond, roles, {"n": "rpm", "T": "degC"})
    assert [(e.driver, e.rows) for e in found] == [("n", 2), ("T", 1)]  # the speed first
    assert found[0].value == 1200.0 and found[0].beyond == pytest.approx(200.0) and found[0].share == pytest.approx(0.2)
    assert found[0].describe() == "n reaches 1200 rpm, 200 rpm above its training range 0 to 1000 rpm (20% of that span)"
    assert "1 K above its training range 20 to 21 °C" in found[1].describe()
    assert ex.excursions(train.assign(n=0.0), beyond, roles)[0].share == float("inf")  # never ran in training


def _idle_1600_8000():
    """Trained on idle and 1600 rpm, the 8000 rpm run held out (the demo spindle network, simulated)."""
    prog = [Block(3.0, 0.0, condition="idle"), Block(3.0, 1600.0), Block(2.0), Block(3.0, 8000.0), Block(2.0)]
    scen = scenarios.blocks(prog, 30.0, ambient=scenarios.daily_cycle(20.0, 22.0, start_hour=7.0), name="case")
    return synthesize(load_network("demo_spindle"), scen, seed=0).recording


def test_automl_flags_the_8000_rpm_run_held_out_after_idle_and_1600_rpm():
    said: list[str] = []
    spec = JobSpec(dataset="sim", model="pipeline", split="condition_holdout",
                   split_params={"test_conditions": ["8000rpm"]}, storage=None, progress=False)
    result = job.run(spec, Settings(budget_fits=10, families=["mlr", "transfer_function"], max_folds=2),
                     say=said.append, recording=_idle_1600_8000())
    first = result.extrapolation[0]
    assert (first.driver, first.value, first.low, first.high) == ("spindle_rpm", 8000.0, 0.0, 1600.0)
    assert first.beyond == pytest.approx(6400.0) and first.share == pytest.approx(4.0)
    assert {e.driver for e in result.extrapolation} >= {"T_front_bearing", "T_rear_bearing"}
    assert said[0].startswith("thermodrift: warning: the held-out part (8000rpm) extrapolates beyond")
    assert result.extrapolates().startswith("the held-out part (8000rpm) extrapolates beyond")
    assert "spindle_rpm reaches 8000 rpm, 6.4e+03 rpm above its training range 0 to 1600 rpm" in said[0]
    board = result.leaderboard
    # the inner fold predicts 1600 rpm from idle: every candidate was validated beyond its training range
    speed = board["params"].map(lambda p: json.loads(p).get("model") == "transfer_function")
    assert board.loc[speed, "inner_extrapolated"].str.contains("spindle_rpm").all()
    assert not board["never_extrapolated"].any()


def _two_drivers() -> Recording:
    """Speed 0 to 1000 rpm then 1500 rpm; a temperature that stays within 20 to 21 °C."""
    t = np.arange(40) * 60.0
    n = np.r_[np.linspace(0, 1000, 20), np.full(10, 1500.0), np.full(10, 3000.0)]
    data = pd.DataFrame({"n": n, "T": 20.0 + 0.5 * (1 + np.sin(t / 600.0)), "d": n / 100.0}, index=t)
    return Recording(data, {"n": Channel("n", "speed", "rpm"), "T": Channel("T", "temperature", "degC"),
                            "d": Channel("d", "displacement", "um")})


def test_a_warning_names_the_held_out_part_once_whatever_the_split():
    rec = _idle_1600_8000()
    for split, params, part in (("condition_holdout", {"test_conditions": ["8000rpm"]}, "(8000rpm)"),
                                ("chronological", {"test_fraction": 0.25}, "(last 25% of time)")):
        (fold,) = splits.make_split(split, **params).folds(rec)
        line = ex.summary(ex.check(rec, fold.train, fold.test, []), ex.held_out_part(fold.name))
        assert line.startswith(f"the held-out part {part} extrapolates beyond the training range")
        assert "held out" not in line
    assert ex.held_out_part("held out: run day06") == "the held-out part (run day06)"


def test_the_leaderboard_marks_candidates_whose_inner_folds_never_extrapolated():
    rec = _two_drivers()
    fold = splits.Fold(np.arange(20), np.arange(20, 30), "inner")
    outer = ex.check(rec, np.arange(30), np.arange(30, 40), ["d"])
    assert [e.driver for e in outer] == ["n"]
    raw = {"model": "mlr", "model_params": {}, "selector": "all", "selector_params": {}, "features": None}
    filtered = {**raw, "features": {"taus_s": [600.0], "powers": [1.0]}}
    board = pd.DataFrame({"trial": [0, 1, -1], "params": [json.dumps(raw), json.dumps(filtered),
                                                          json.dumps({"members": [0, 1], "weights": [0.5, 0.5]})]})
    marked = ex.mark(board, rec, [fold], ["d"], registry, outer)
    # raw mlr reads the temperature only, which no fold took beyond its range; the filtered one reads the speed
    assert marked["inner_extrapolated"].tolist() == ["", "n", "n"]
    assert marked["never_extrapolated"].tolist() == [True, False, False]


def test_a_streamed_input_is_said_once_when_it_leaves_its_training_range():
    watch = ex.Watch({"n": {"min": 0.0, "max": 1000.0}, "T": {"min": 20.0, "max": 21.0}}, ["n", "T"],
                     {"n": "speed", "T": "temperature"}, {"n": "rpm", "T": "degC"})
    assert watch.update(np.array([1050.0, 21.2])) == []
    assert watch.update(np.array([1200.0, np.nan])) == ["n"]
    assert watch.update(np.array([1500.0, 22.0])) == ["T"]
    assert watch.update(np.array([1300.0, 20.5])) == []
    found = watch.found()
    assert [(e.driver, e.value, e.rows) for e in found] == [("n", 1500.0, 3), ("T", 22.0, 1)]


@pytest.mark.skipif(not WORKBOOK.is_file(), reason=f"FL_THERMAL workbook not available at {WORKBOOK}")
def test_fl_thermal_final_block_is_not_flagged_and_the_5000_rpm_run_is():
    rec = registry.create("dataset", "fl_thermal", path=str(WORKBOOK))
    (final,) = splits.make_split("time_window", train_end_h=40.13, test_start_h=40.13).folds(rec)
    assert ex.check(rec, final.train, final.test, ["ch3(um)"]) == []
    (fold,) = splits.make_split("time_window", train_end_h=24.13, test_start_h=24.13, test_end_h=32.13).folds(rec)
    found = ex.check(rec, fold.train, fold.test, ["ch3(um)"])
    assert found[0].driver == "spindle(RPM)" and found[0].value == pytest.approx(5000, abs=20)
