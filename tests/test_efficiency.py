"""Every job measures its refit model's costs (S3 Table 14): training s, latency per sample, parameter count."""

from __future__ import annotations

import numpy as np
import pytest

from thermodrift.core.study import Job, JobSpec
from thermodrift.testing.data import tiny_recording

pytestmark = pytest.mark.usefixtures("one_torch_thread")
DLTK_TINY = dict(channels=4, hidden_size=8, heads=2, kan_grid=2, window=4,
                 trainer=dict(epochs=4, t0=2, batch_size=64, device="cpu"))


def test_a_job_records_the_refit_models_costs():
    spec = JobSpec(dataset="tiny", model="dltk", selector="all", split="chronological", model_params=DLTK_TINY,
                   n_trials=0, baselines=("mlr",), storage=None, progress=False)
    result = Job(spec).run(tiny_recording())
    cost = result.folds[-1].efficiency
    assert set(cost) == {"train_s", "latency_batch_ms", "latency_stream_ms", "n_parameters"}
    assert cost["n_parameters"] == result.model.train_report_.n_parameters == result.model.n_parameters() > 0
    assert cost["train_s"] > 0 and cost["latency_batch_ms"] > 0
    assert cost["latency_stream_ms"] > cost["latency_batch_ms"]  # one row per call pays the per-call overhead


def test_a_linear_model_counts_its_coefficients():
    spec = JobSpec(dataset="tiny", model="mlr", selector="all", split="chronological", n_trials=0,
                   baselines=("mlr",), storage=None, progress=False)
    result = Job(spec).run(tiny_recording())
    ridge = result.model.regressor_
    # 2 targets x (5 sensors + 1)
    assert result.folds[-1].efficiency["n_parameters"] == np.size(ridge.coef_) + np.size(ridge.intercept_) == 12


def test_an_untuned_job_logs_its_costs_to_mlflow(tmp_path, monkeypatch):
    import mlflow

    from thermodrift.core import tracking

    monkeypatch.chdir(tmp_path)
    spec = JobSpec(dataset="tiny", model="mlr", selector="all", split="chronological", n_trials=0,
                   baselines=("mlr",), storage=None, progress=False)
    result = Job(spec).run(tiny_recording())
    tracking.setup(f"sqlite:///{tmp_path / 'mlflow.db'}", "s3-efficiency")
    with mlflow.start_run() as run:
        tracking.log_result(result, {"model": {"name": "mlr"}})
    metrics = mlflow.get_run(run.info.run_id).data.metrics
    assert metrics["efficiency/n_parameters"] == 12 and metrics["efficiency/latency_batch_ms"] > 0
    assert metrics["study/n_trials"] == 0 and metrics["valid/best_rmse"] == pytest.approx(result.valid_rmse)
