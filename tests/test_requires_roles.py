"""Machines without a speed signal: a family declares the roles it cannot run without (``requires_roles``), a job
refuses it in one line, and AutoML leaves it out before fitting, naming it and why, and runs every other family."""

from __future__ import annotations

import pytest

from thermodrift.core import registry
from thermodrift.core.automl import job, space
from thermodrift.core.automl.evaluate import Evaluator
from thermodrift.core.automl.search import Settings
from thermodrift.core.errors import InputError
from thermodrift.core.recording import Recording
from thermodrift.core.study import Job, JobSpec
from thermodrift.testing.data import tiny_recording


def no_speed() -> Recording:
    """The tiny spindle recording as a lathe without a speed signal records it: temperatures and drift only."""
    rec = tiny_recording()
    channels = {c: ch for c, ch in rec.channels.items() if ch.role != "speed"}
    return Recording(rec.data[list(channels)], channels, source="no_speed.csv")


def _spec(**kw) -> JobSpec:
    return JobSpec(**{"dataset": "recording_file", "model": "mlr", "storage": None, "progress": False, "seed": 0, **kw})


def test_the_physics_families_declare_speed_and_every_other_family_runs_without_it():
    reg = registry.default()
    needs = {n for n in reg.names("model") if getattr(reg.get("model", n).factory, "requires_roles", ())}
    assert {"lptn", "lptn_hybrid"} <= needs
    roles = {ch.role for ch in no_speed().channels.values()}
    everything = {f.name for f in space.families()}
    assert {"lptn", "lptn_hybrid", "mlr"} <= everything  # without roles to check, nothing is left out
    kept = {f.name for f in space.families(roles=roles)}
    assert kept == everything - needs and "mlr" in kept and "transfer_function" in kept
    building = {"greybox"}  # needs a heating channel, which no machine has
    assert space.left_out(roles) == {n: ["heating"] if n in building else ["speed"] for n in needs & everything}
    with_speed = {ch.role for ch in tiny_recording().channels.values()}
    assert space.left_out(with_speed) == {n: ["heating"] for n in building}
    assert {f.name for f in space.families(roles=with_speed)} == everything - building


def test_automl_names_the_families_it_leaves_out_before_fitting_and_runs_the_rest(monkeypatch):
    said: list[str] = []
    fitted = Evaluator.evaluate

    def evaluate(self, params, *args, **kwargs):  # every candidate's fit passes here
        said.append(f"fit {params['model']}")
        return fitted(self, params, *args, **kwargs)

    monkeypatch.setattr(Evaluator, "evaluate", evaluate)
    families = ["mlr", "transfer_function", "lptn", "lptn_hybrid"]
    result = job.run(_spec(split="chronological"), Settings(budget_fits=12, families=families, max_folds=2),
                     say=said.append, recording=no_speed())
    line = ("automl: left out before fitting, no_speed.csv has no such channel: lptn, lptn_hybrid (need a channel "
            "of role speed)")
    assert said[0] == line and said.count(line) == 1  # first, before any fit
    assert not any(s.startswith("fit lptn") for s in said)
    board = result.leaderboard
    assert set(board.loc[board["model"] != "ensemble", "model"]) == {"mlr", "transfer_function"}
    assert (board["status"] == "ok").all()  # nothing failed: what cannot run was never tried

    with pytest.raises(InputError, match="no automl family can run on this recording") as err:
        job.run(_spec(split="chronological"), Settings(budget_fits=4, families=["lptn"], max_folds=2),
                recording=no_speed())
    assert "lptn (needs a channel of role speed)" in str(err.value)


def test_a_job_refuses_a_model_that_needs_speed_in_one_line():
    with pytest.raises(InputError, match="model lptn needs a channel of role speed, and the recording has none"):
        Job(_spec(model="lptn", split="chronological", n_trials=0)).run(no_speed())
