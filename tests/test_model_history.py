"""Models with history see the real input rows before a held-out part, and their streamers agree with it."""

import numpy as np
import pytest

from thermodrift.core.study import Job, JobSpec, model_inputs
from thermodrift.plugins.models.lstm import LSTM
from thermodrift.plugins.models.transfer_function import TransferFunction
from thermodrift.testing.data import tiny_recording

CASES = [("transfer_function", TransferFunction, {}),
         ("lstm", LSTM, {"hidden_units": 4, "window": 5, "trainer": {"epochs": 20, "t0": 5}})]


@pytest.mark.parametrize("name,cls,params", CASES, ids=[c[0] for c in CASES])
def test_held_out_first_rows_see_the_real_history(name, cls, params):
    rec = tiny_recording()
    spec = JobSpec(dataset="tiny", model=name, selector="all", split="chronological", n_trials=0,
                   model_params=params, baselines=(), storage=None, progress=False,
                   split_params={"test_fraction": 0.3})
    fold = Job(spec).run(recording=rec).folds[0]
    model = fold.model
    X = model_inputs(rec, fold.selected, cls, list(fold.y_true.columns))
    first = int(np.searchsorted(rec.time_s, fold.time_s[0]))
    with_history = model.predict(X.iloc[first:], history=X.iloc[:first])
    cold = model.predict(X.iloc[first:])
    got = fold.predictions["model"]
    np.testing.assert_allclose(got, with_history, atol=1e-6)
    # the first held-out rows are where history matters: a cold start predicts them differently
    assert np.abs(got[:3] - cold[:3]).max() > 1e-3


def test_transfer_function_streams_fast_and_exactly():
    rec = tiny_recording()
    temps = rec.columns("temperature")
    X = model_inputs(rec, temps, TransferFunction, [])
    y = rec.data[rec.columns("displacement")]
    model = TransferFunction().fit(X.iloc[:200], y.iloc[:200])
    batch = model.predict(X.iloc[200:], history=X.iloc[:200])
    stream = model.streamer(X.iloc[:200])
    rows = X.iloc[200:].to_dict("records")
    streamed = np.array([stream.update(r) for r in rows])
    np.testing.assert_allclose(streamed, batch, atol=1e-9)
    # the streamer carries its state instead of re-running the filters over the past (an O(1) update)
    assert not hasattr(stream, "_rows")


def test_selector_search_space_is_tuned_jointly_on_inner_training_rows(monkeypatch):
    from thermodrift.core import registry, splits
    from thermodrift.plugins.selectors.correlation_top_k import CorrelationTopK

    seen = []

    class Noting(CorrelationTopK):
        def _select(self, X, y):
            seen.append((self.k, set(X.index)))
            return super()._select(X, y)

    reg = registry.load()
    reg.add("selector", "noting_top_k", Noting, origin="tests", module=__name__)
    monkeypatch.setattr(registry, "_DEFAULT", reg)
    rec = tiny_recording()
    spec = JobSpec(dataset="tiny", model="mlr", selector="noting_top_k", optimizer="random", split="chronological",
                   n_trials=6, storage=None, progress=False, baselines=(),
                   selector_search_space={"k": {"type": "int", "low": 1, "high": 4}})
    result = Job(spec).run(recording=rec)
    fold = splits.make_split("chronological").folds(rec)[0]
    inner = splits.inner_fold(rec.select(fold.train))
    times = rec.data.index.to_numpy()
    inner_train = set(times[fold.train[inner.train]])
    per_trial = seen[1:-1]  # the first fit uses the defaults on the training part, the last refits the best
    assert len(per_trial) == 6 and {k for k, _ in per_trial} != {4}  # k varies across trials
    assert all(rows == inner_train for _, rows in per_trial)  # each trial selects on inner training rows only
    study = result.study
    assert seen[-1][0] == study.best_params["selector.k"] and seen[-1][1] == set(times[fold.train])
    assert 1 <= len(result.selected) <= study.best_params["selector.k"]
