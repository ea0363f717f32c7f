"""Models with history see the real input rows before a held-out part, and their streamers agree with it."""

import numpy as np
import pytest

from thermodrift.core.study import Job, JobSpec, model_inputs
from thermodrift.plugins.models.lstm import LSTM
from thermodrift.plugins.models.transfer_function import TransferFunction
from thermodrift.testing.data import tiny_recording

CASES = [("transfer_function", TransferFunction, {}),
         ("lstm", LSTM, {"hidden_units": 4, "epochs": 20, "t0": 5, "window": 5})]


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
