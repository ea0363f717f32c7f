"""No test row of a fold reaches what produces that fold's prediction: selection, tuning, scaling or refit.

A recording selector and a recording model (with history, so the history passed to it is checked too) note the
rows of every call; the calls are cut into folds at each selector fit (the job runs its folds one after another).
Models scale inside their own ``fit``, so the rows that reach ``fit`` are the rows that reach scaling.
"""

import numpy as np
import pytest

from thermodrift.core import registry, splits
from thermodrift.core.study import Job, JobSpec
from thermodrift.plugins.models.mlr import MLR
from thermodrift.plugins.selectors.correlation_top_k import CorrelationTopK
from thermodrift.testing.data import tiny_recording

CALLS: list[tuple[str, np.ndarray]] = []


class RecordingSelector(CorrelationTopK):
    def _select(self, X, y):
        CALLS.append(("select", X.index.to_numpy()))
        return super()._select(X, y)


class RecordingModel(MLR):
    history_length = None  # the whole past: every history the job passes is recorded

    def _fit(self, X, y):
        CALLS.append(("fit", X.index.to_numpy()))
        super()._fit(X, y)

    def predict(self, X, history=None):
        CALLS.append(("history", np.asarray([] if history is None else history.index.to_numpy())))
        CALLS.append(("predict", X.index.to_numpy()))
        return super().predict(X, history)


# Every honest split kind, with parameters that fit the 5-hour tiny recording (5 working conditions).
HONEST = {
    "chronological": {},
    "condition_holdout": {},
    "condition_holdout/others": {"test_conditions": ["c02"], "train_on": "others"},
    "time_window": {"train_end_h": 3.0, "test_start_h": 3.0, "test_end_h": 4.0},
    "forward_chaining": {},
    "run_holdout": {"test_runs": ["r1"]},
    "leave_one_run_out": {},
    "run_forward_chaining": {},
}
RUN_SPLITS = ("run_holdout", "leave_one_run_out", "run_forward_chaining")


def three_runs():
    """Three tiny recordings as independent runs r0, r1, r2 (the run splits need several)."""
    import pandas as pd

    from thermodrift.core.recording import Recording

    parts = [tiny_recording(seed=s).data for s in range(3)]
    data = pd.concat([p.set_axis(p.index + 1e5 * k, axis=0) for k, p in enumerate(parts)])
    return Recording(data, tiny_recording(0).channels, runs=[f"r{k}" for k, p in enumerate(parts) for _ in p.index])


def test_every_honest_split_kind_is_covered():
    honest = {k for k, cls in splits.SPLITS.items() if cls.protocol == "honest"}
    assert honest == {k.split("/")[0] for k in HONEST}


@pytest.fixture()
def reg(monkeypatch):
    loaded = registry.load()
    tests = loaded.registrar("tests", __name__)
    tests.add("model", "recording_mlr", RecordingModel)
    tests.add("selector", "recording_top_k", RecordingSelector)
    monkeypatch.setattr(registry, "_DEFAULT", loaded)
    return loaded


@pytest.mark.parametrize("case", list(HONEST))
def test_no_test_row_reaches_selection_tuning_or_refit(reg, case):
    kind, params = case.split("/")[0], HONEST[case]
    rec = three_runs() if kind in RUN_SPLITS else tiny_recording(seed=0)
    spec = JobSpec(dataset="tiny", model="recording_mlr", selector="recording_top_k", optimizer="random",
                   split=kind, split_params=params, n_trials=3, storage=None, progress=False,
                   selector_search_space={})  # one selection per fold; joint tuning: tests/test_model_history.py
    CALLS.clear()
    result = Job(spec).run(rec)
    folds = splits.make_split(kind, **params).folds(rec)
    assert len(result.folds) == len(folds)
    index = rec.data.index
    starts = [i for i, (what, _) in enumerate(CALLS) if what == "select"]
    for fold in folds:
        assert any(set(index.get_indexer(CALLS[i][1])) <= set(fold.train) for i in starts), \
            f"{case} {fold.name}: no selection saw this fold's training rows alone"
    assert len(starts) == len(folds), "one selection per fold"
    for fold, start, end in zip(folds, starts, starts[1:] + [len(CALLS)]):
        test = set(fold.test)
        calls = [(what, set(index.get_indexer(rows))) for what, rows in CALLS[start:end]]
        held_out = max(i for i, (what, _) in enumerate(calls) if what == "predict")
        assert calls[held_out][1] == test  # the refit model's held-out prediction
        if np.all(np.diff(fold.test) == 1):  # ... with every earlier input row as its history
            assert calls[held_out - 1][1] == set(range(fold.test[0]))
        fits = [i for i, (what, _) in enumerate(calls) if what == "fit"]
        assert len(fits) >= 2 and calls[fits[-1]][1] <= set(fold.train)  # tuning fits, then the refit
        for i, (what, rows) in enumerate(calls):
            if i != held_out:
                assert not rows & test, f"{case} {fold.name}: test rows reach the {what} call #{i}"


class RunningSum(MLR):
    """A stateful toy: the prediction is the running sum of the first input column over history and X."""

    history_length = None

    def _fit(self, X, y):
        self.k_ = y.shape[1]

    def _predict(self, X):
        return np.repeat(np.cumsum(X.iloc[:, 0].to_numpy())[:, None], self.k_, axis=1)


def test_predict_rows_gives_history_models_only_the_rows_before():
    import pandas as pd

    from thermodrift.core.study import predict_rows

    frame = pd.DataFrame({"T": np.ones(10)})
    model = RunningSum().fit(frame, pd.DataFrame({"y": np.zeros(10)}))
    # held-out: every earlier input row is history, also across gaps between held-out blocks
    np.testing.assert_array_equal(predict_rows(model, frame, np.array([5, 6, 7]))[:, 0], [6, 7, 8])
    np.testing.assert_array_equal(predict_rows(model, frame, np.array([2, 8]))[:, 0], [3, 9])
    # inner validation: only the unbroken run of allowed (training) rows just before each block
    allowed = np.array([0, 1, 4, 5, 6, 7])
    np.testing.assert_array_equal(predict_rows(model, frame, np.array([6, 7]), allowed)[:, 0], [3, 4])
    np.testing.assert_array_equal(predict_rows(model, frame, np.array([1, 5]), allowed)[:, 0], [2, 2])
