"""Several independent runs per machine: no filter, state or sequence window crosses a run boundary (batch and
streaming), tables become runs, splits and AutoML's inner folds go by run, bad multi-run input is one line."""

import numpy as np
import pandas as pd
import pytest

from thermodrift import compensator
from thermodrift.compensator import limits, package
from thermodrift.core import registry, splits
from thermodrift.core.automl.folds import inner_folds
from thermodrift.core.errors import InputError
from thermodrift.core.recording import Recording, load_recording
from thermodrift.core.study import model_inputs, predict_rows
from thermodrift.testing.data import tiny_recording

HISTORY_MODELS = [
    ("pipeline", {"model": "mlr", "features": {"taus_s": [600.0, 3000.0], "powers": [1.0]}}),
    ("transfer_function", {"n_taus": 2}),
    ("lstm", {"window": 6, "hidden_units": 4, "trainer": {"epochs": 2, "t0": 2, "batch_size": 64}}),
]


def two_runs(order="ab") -> Recording:
    """Two tiny recordings as runs ``a`` and ``b`` (b offset by 3 µm), in ``order``; the second one's times
    follow the first's (each starts cold)."""
    rec = {"a": tiny_recording(seed=1), "b": tiny_recording(seed=2)}
    parts = {k: r.data.copy() for k, r in rec.items()}
    parts["b"][rec["a"].columns("displacement")] += 3.0
    first, second = parts[order[0]], parts[order[1]]
    second.index = second.index - second.index[0] + first.index[-1] + 60.0
    return Recording(pd.concat([first, second]), rec["a"].channels,
                     runs=[order[0]] * len(first) + [order[1]] * len(second))


def alone(rec: Recording, run: str) -> Recording:
    rows = np.flatnonzero(rec.runs().to_numpy() == run)
    return Recording(rec.data.iloc[rows], rec.channels)  # a recording of one run: no boundaries at all


def frame(rec, name, params):
    targets = rec.columns("displacement")
    cls = registry.get("model", name).factory
    return model_inputs(rec, rec.columns("temperature"), cls, targets), rec.data[targets]


@pytest.mark.parametrize("name,params", HISTORY_MODELS, ids=[m[0] for m in HISTORY_MODELS])
def test_predictions_on_a_run_do_not_depend_on_the_run_before_it(name, params):
    rec = two_runs()
    X, y = frame(rec, name, params)
    model = registry.create("model", name, **params).fit(X, y)
    rows_b = np.flatnonzero(rec.runs().to_numpy() == "b")
    Xb, _ = frame(alone(rec, "b"), name, params)
    assert model.history_length != 0
    expected = model.predict(Xb)
    np.testing.assert_allclose(model.predict(X)[rows_b], expected, atol=1e-5)
    # as a study predicts held-out rows: every earlier row offered as history, the filters still start at b
    np.testing.assert_allclose(predict_rows(model, X, rows_b), expected, atol=1e-5)
    np.testing.assert_allclose(predict_rows(model, X, rows_b, allowed=np.arange(rows_b[0])), expected, atol=1e-5)
    # streaming after a history of run a and b's first k rows equals streaming b from its first row
    k = 3
    streamed = model.streamer(X.iloc[:rows_b[k]])
    fresh = model.streamer(None)
    for i in range(k):
        fresh.update(Xb.iloc[i])
    for i in range(k, k + 4):
        np.testing.assert_allclose(streamed.update(X.iloc[rows_b[i]]), fresh.update(Xb.iloc[i]), atol=1e-5)


def test_fitting_reads_no_filter_across_a_boundary():
    """Fitted on runs a, b or on b, a: the same model (a filter running over the boundary would differ)."""
    name, params = HISTORY_MODELS[0]
    ab, ba = two_runs("ab"), two_runs("ba")
    m_ab = registry.create("model", name, **params).fit(*frame(ab, name, params))
    m_ba = registry.create("model", name, **params).fit(*frame(ba, name, params))
    X1, _ = frame(alone(ab, "a"), name, params)
    np.testing.assert_allclose(m_ab.predict(X1), m_ba.predict(X1), atol=1e-8)
    # the windows of a sequence model: run b's first window holds b's first row only
    lstm = registry.create("model", "lstm", window=4)
    X, _ = frame(ab, "lstm", {})
    w = lstm._inputs(X)
    first_b = int(np.flatnonzero(ab.runs().to_numpy() == "b")[0])
    np.testing.assert_array_equal(w[first_b], np.repeat(X.to_numpy()[first_b:first_b + 1], 4, axis=0))


def test_the_compensator_starts_each_run_afresh(tmp_path):
    rec = two_runs()
    X, y = frame(rec, *HISTORY_MODELS[0])
    model = registry.create("model", "pipeline", **HISTORY_MODELS[0][1]).fit(X, y)
    lim = limits.training_limits(X.to_numpy(), list(X.columns), y.to_numpy(), list(y.columns), X.index.to_numpy())
    package.write(package.document(model.export_state(), lim), tmp_path)
    pkg = compensator.load(tmp_path)
    rows_b = np.flatnonzero(rec.runs().to_numpy() == "b")
    values = X[pkg.inputs].to_numpy()
    across = pkg.compensator(limits=False)
    for i in range(rows_b[0]):
        across.update(float(X.index[i]), values[i])
    across.new_run()
    fresh = pkg.compensator(limits=False)
    for i in rows_b[:20]:
        np.testing.assert_allclose(across.update(float(X.index[i]), values[i]).written,
                                   fresh.update(float(X.index[i]), values[i]).written, atol=1e-9)
    np.testing.assert_allclose(fresh.update(float(X.index[rows_b[20]]), values[rows_b[20]]).raw,
                               model.predict(X.iloc[rows_b[:21]])[-1], atol=1e-6)


def test_tables_and_run_columns_load_as_runs(tmp_path):
    rec = two_runs()
    rec.write(tmp_path / "both.csv", tmp_path / "both.yaml")
    back = load_recording(tmp_path / "both.csv", tmp_path / "both.yaml")
    assert back.run_names == ["a", "b"] and back.run_starts_s == rec.run_starts_s
    for run in ("a", "b"):
        alone(rec, run).write(tmp_path / f"day_{run}.csv", tmp_path / "one.yaml")
    files = load_recording(str(tmp_path / "day_*.csv"), tmp_path / "one.yaml")
    assert files.run_names == ["day_a", "day_b"]
    assert np.all(np.diff(files.time_s) > 0)  # day_b's times (starting again at 0) follow day_a's
    np.testing.assert_allclose(files.data.to_numpy(), rec.data.to_numpy())
    assert "runs (2" in files.summary() and "day_b" in files.summary()


def test_splits_and_inner_folds_go_by_run():
    rec = Recording(pd.concat([tiny_recording(seed=s).data.set_axis(
        tiny_recording(seed=s).data.index + 1e6 * s, axis=0) for s in range(5)]),
        tiny_recording(0).channels, runs=[f"d{s}" for s in range(5) for _ in range(len(tiny_recording(s)))])
    runs = rec.runs().to_numpy()
    held = splits.make_split("run_holdout", test_runs=["d3"]).folds(rec)[0]
    assert set(runs[held.test]) == {"d3"} and "d3" not in set(runs[held.train])
    loro = splits.make_split("leave_one_run_out").folds(rec)
    assert [set(runs[f.test]) for f in loro] == [{f"d{s}"} for s in range(5)]
    chain = splits.make_split("run_forward_chaining", min_train_runs=2).folds(rec)
    assert [sorted(set(runs[f.train])) for f in chain] == [["d0", "d1"], ["d0", "d1", "d2"], ["d0", "d1", "d2", "d3"]]
    folds = inner_folds(rec, held.train, max_folds=3)
    validated = [set(runs[f.test]) for f in folds]
    assert set().union(*validated) == {"d0", "d1", "d2", "d4"}  # every training run, not only the last ones
    for f in folds:
        assert not set(runs[f.train]) & set(runs[f.test]) and "d3" not in set(runs[f.train])


@pytest.mark.parametrize("case", ["empty_run", "other_channels", "never_measured", "run_again"])
def test_bad_multi_run_input_is_one_line(tmp_path, cli, case):
    rec = two_runs()
    a, b = alone(rec, "a"), alone(rec, "b")
    a.write(tmp_path / "a.csv", tmp_path / "m.yaml")
    b.write(tmp_path / "b.csv", tmp_path / "m.yaml")
    target = rec.columns("displacement")[0]
    table = pd.read_csv(tmp_path / "b.csv")
    if case == "empty_run":
        table.iloc[:0].to_csv(tmp_path / "b.csv", index=False)
    elif case == "other_channels":
        table.drop(columns=[rec.columns("temperature")[0]]).to_csv(tmp_path / "b.csv", index=False)
    elif case == "never_measured":
        table.assign(**{target: np.nan}).to_csv(tmp_path / "b.csv", index=False)
    tables = [str(tmp_path / "a.csv"), str(tmp_path / "b.csv")]
    if case == "run_again":
        rec.write(tmp_path / "r.csv", tmp_path / "m.yaml")
        r = pd.read_csv(tmp_path / "r.csv")
        pd.concat([r, r.iloc[:20].assign(time_s=r["time_s"].iloc[-1] + 60.0 * np.arange(1, 21))]).to_csv(
            tmp_path / "r.csv", index=False)
        tables = [str(tmp_path / "r.csv")]
    result = cli(tmp_path, "validate", *tables, "--manifest", str(tmp_path / "m.yaml"))
    assert result.returncode == 2, result.stdout + result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr
    assert {"empty_run": "no data rows", "other_channels": "no such column", "never_measured": "never measured",
            "run_again": "appears again"}[case] in lines[0]


def test_compensate_starts_a_new_run_where_the_run_column_changes():
    import io

    from thermodrift.compensator import stream

    class Recorder:
        def __init__(self):
            self.calls = []

        def update(self, t, values):
            self.calls.append(("update", t))
            return None

        def new_run(self):
            self.calls.append(("new_run", None))

    class Writer:
        def header(self):
            return ["time_s"]

        def rows(self, step):
            return []

    rows = [[0, 20.0, "mon"], [60, 20.5, "mon"], [0, 19.0, "tue"], [60, 19.5, "tue"]]
    parse = stream.Rows(["t", "T", "day"], "t", 1.0, ["T"], {"T": (1.0, 0.0)}, run_column="day")
    comp = Recorder()
    stream.run(comp, Writer(), rows, parse, io.StringIO())
    assert [c[0] for c in comp.calls] == ["update", "update", "new_run", "update", "update"]
