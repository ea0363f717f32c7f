"""A drift measured now and then: NaN between measurements loads, models fit on the measured rows with inputs and
histories at full rate, metrics use the measured rows, and inputs still refuse long gaps."""

import numpy as np
import pandas as pd
import pytest

from thermodrift.core import registry
from thermodrift.core.automl import job as automl_job
from thermodrift.core.automl.search import Settings
from thermodrift.core.errors import InputError
from thermodrift.core.metrics import evaluate
from thermodrift.core.recording import Recording, load_recording
from thermodrift.core.study import JobSpec, model_inputs
from thermodrift.testing.data import tiny_recording

EVERY = 17  # rows between measurements: no pattern of the tiny recording's sampling


def sparse_tiny(seed=0) -> Recording:
    rec = tiny_recording(seed=seed)
    data = rec.data.copy()
    off = np.arange(len(data)) % EVERY != 0
    data.loc[off, rec.columns("displacement")] = np.nan
    return Recording(data, rec.channels)


def test_a_sparse_drift_loads_and_a_long_input_gap_is_still_refused(tmp_path):
    sparse_tiny().write(tmp_path / "s.csv", tmp_path / "m.yaml")
    rec = load_recording(tmp_path / "s.csv", tmp_path / "m.yaml")
    target = rec.columns("displacement")[0]
    assert np.isfinite(rec.data[target]).sum() == len(rec.data[::EVERY])
    assert any("sparse" in n for n in rec.notes) and "measured in" in rec.summary()
    table = pd.read_csv(tmp_path / "s.csv")
    table.loc[20:30, rec.columns("temperature")[0]] = np.nan
    table.to_csv(tmp_path / "s.csv", index=False)
    with pytest.raises(InputError, match="missing values in a row"):
        load_recording(tmp_path / "s.csv", tmp_path / "m.yaml")


def inputs(rec, name):
    targets = rec.columns("displacement")
    return model_inputs(rec, rec.columns("temperature"), registry.get("model", name).factory, targets), \
        rec.data[targets]


def test_models_fit_on_the_measured_rows_with_full_rate_histories():
    rec = sparse_tiny()
    X, y = inputs(rec, "pipeline")
    measured = np.flatnonzero(np.isfinite(y.to_numpy()).all(axis=1))
    # a memoryless model: the same fit as on the measured rows alone
    mlr_X, _ = inputs(rec, "mlr")
    sparse = registry.create("model", "mlr").fit(mlr_X, y)
    alone = registry.create("model", "mlr").fit(mlr_X.iloc[measured], y.iloc[measured])
    np.testing.assert_allclose(sparse.predict(mlr_X), alone.predict(mlr_X), atol=1e-9)
    # a filter pipeline: features from every input row, its read-out fitted on the measured rows' features
    pipe = registry.create("model", "pipeline", model="mlr", features={"taus_s": [300.0, 1200.0]}).fit(X, y)
    F = pipe._inner_frame(X)
    readout = registry.create("model", "mlr").fit(F.iloc[measured], y.iloc[measured])
    np.testing.assert_allclose(pipe.predict(X), readout.predict(F), atol=1e-9)
    subsampled = registry.create("model", "mlr").fit(
        pipe._inner_frame(X.iloc[measured]), y.iloc[measured])  # what filters over the probe rows would give
    assert not np.allclose(pipe.predict(X), subsampled.predict(F), atol=1e-3)
    for name, params in [("transfer_function", {"n_taus": 2}),
                         ("lstm", {"window": 4, "hidden_units": 2, "trainer": {"epochs": 2, "t0": 2}})]:
        Xm, ym = inputs(rec, name)
        pred = registry.create("model", name, **params).fit(Xm, ym).predict(Xm)
        assert pred.shape == ym.shape and np.isfinite(pred).all()


def test_metrics_use_the_measured_rows():
    y = pd.DataFrame({"d": [1.0, np.nan, 3.0, np.nan, 5.0]})
    pred = np.array([1.5, 100.0, 2.0, -100.0, 5.0])
    assert evaluate(y, pred)["d"] == evaluate(y.iloc[[0, 2, 4]], pred[[0, 2, 4]])["d"]


def test_automl_runs_on_a_sparse_drift():
    rec = sparse_tiny()
    spec = JobSpec(dataset="tiny", model="mlr", split="condition_holdout", seed=0, storage=None, progress=False)
    result = automl_job.run(spec, Settings(budget_fits=8, families=["mlr", "transfer_function"]), recording=rec)
    assert np.isfinite(result.job.summary_metrics("model")["rmse"])


def test_a_sparse_target_caps_parameters_by_its_measurements_and_is_not_tuned():
    rec = tiny_recording(seed=0)
    data = rec.data.copy()
    off = np.arange(len(data)) % 40 != 0  # 7 measured training rows: fewer than mlr's 12 weights on 2 targets
    data.loc[off, rec.columns("displacement")] = np.nan
    rec = Recording(data, rec.channels)
    spec = JobSpec(dataset="tiny", model="mlr", split="condition_holdout", seed=0, storage=None, progress=False)
    lines = []
    result = automl_job.run(spec, Settings(budget_fits=12, families=["mlr", "transfer_function"]), recording=rec,
                            say=lines.append)
    assert "automl: mlr · all · raw left out: 12 parameters, more than the 7 measured rows of the training part" \
        in lines[0] and sum("left out:" in line for line in lines) == 1  # one line for the family
    assert any("no TPE tuning" in line for line in lines)
    board = result.leaderboard
    assert board.loc[board["model"] == "mlr", "error"].str.startswith("left out: ").all()
    assert board.loc[board["model"] == "transfer_function", "status"].eq("ok").all()
    assert "tpe" not in set(board["phase"]) and result.search.fits == len(result.search.folds)  # left out: unscored


def test_a_dense_target_is_neither_capped_nor_left_untuned():
    from thermodrift.core.automl.evaluate import Evaluator
    from thermodrift.core.automl.folds import inner_folds

    rec = tiny_recording(seed=0)
    data = rec.data.copy()
    data.loc[data.index[::3], rec.columns("displacement")] = np.nan  # dropouts, not a drift measured now and then
    rec = Recording(data, rec.channels)
    train = np.arange(200)
    ev = Evaluator(rec, train, rec.columns("displacement"), inner_folds(rec, train))
    assert ev.max_parameters is None
