"""AutoML's inner folds and portfolio in parallel processes: the leaderboard does not depend on ``n_jobs``."""

import pandas as pd

from thermodrift.core.automl import job as automl_job
from thermodrift.core.automl.leaderboard import TIMING
from thermodrift.core.automl.search import Settings
from thermodrift.core.study import JobSpec
from thermodrift.testing.data import tiny_recording


def board(n_jobs: int) -> tuple[pd.DataFrame, float]:
    spec = JobSpec(dataset="tiny", model="mlr", split="condition_holdout", seed=3, storage=None, progress=False)
    settings = Settings(budget_fits=36, families=["mlr", "transfer_function"], n_jobs=n_jobs)
    result = automl_job.run(spec, settings, recording=tiny_recording(seed=1))
    return result.leaderboard.drop(columns=list(TIMING)), result.job.summary_metrics("model")["rmse"]


def test_the_leaderboard_does_not_depend_on_n_jobs():
    one, rmse_one = board(1)
    two, rmse_two = board(2)
    assert set(one["phase"]) >= {"portfolio", "tpe"} and (one["status"] == "ok").sum() >= 10
    pd.testing.assert_frame_equal(one, two)
    assert rmse_one == rmse_two
