"""The windowed torch models share one base (plugins/models/_sequence.py): windows, history and a streamer that
keeps its window incrementally."""

import numpy as np
import pytest

from thermodrift.core import registry
from thermodrift.plugins.models import lstm as lstm_module
from thermodrift.plugins.models._sequence import SequenceModel, SequenceStreamer, windows
from thermodrift.testing import tiny_frames

SEQUENCE_MODELS = ["lstm", "cnn_lstm", "ma_cnn", "cnn_lstm_transformer", "tcn_lstm", "dltk"]
TINY = {"trainer": {"epochs": 2, "t0": 1, "batch_size": 64}}


def _fitted(name: str, **params):
    X, y = tiny_frames()
    return registry.create("model", name, **{**TINY, **params}).fit(X.iloc[:200], y.iloc[:200]), X


@pytest.mark.parametrize("name", SEQUENCE_MODELS)
def test_every_windowed_model_is_a_sequence_model(name):
    model = registry.create("model", name, window=4)
    assert isinstance(model, SequenceModel)
    assert model.history_length == 3


def test_lstm_has_no_windowing_of_its_own():
    assert not hasattr(lstm_module, "windows")
    assert "_inputs" not in vars(lstm_module.LSTM) and "history_length" not in vars(lstm_module.LSTM)


def test_windows_pad_with_the_first_row():
    x = np.arange(6, dtype=float).reshape(3, 2)
    w = windows(x, 3)
    assert w.shape == (3, 3, 2)
    np.testing.assert_array_equal(w[0], [[0, 1], [0, 1], [0, 1]])
    np.testing.assert_array_equal(w[2], [[0, 1], [2, 3], [4, 5]])


@pytest.mark.parametrize("name", ["lstm", "tcn_lstm"])
def test_one_forward_pass_of_one_window_per_update(name):
    model, X = _fitted(name, window=5)
    streamer = model.streamer(X.iloc[:200])
    assert isinstance(streamer, SequenceStreamer)
    shapes = []
    handle = streamer.module.register_forward_hook(lambda mod, args, out: shapes.append(tuple(args[0].shape)))
    try:
        for i in range(200, 210):
            streamer.update(X.iloc[i])
    finally:
        handle.remove()
    assert shapes == [(1, 5, X.shape[1])] * 10


@pytest.mark.parametrize("history_rows", [0, 1, 2, 4, 50])
def test_streaming_equals_batch_for_any_history_length(history_rows):
    """Fewer history rows than the window: the streamer pads with the oldest row, as ``windows`` does."""
    model, X = _fitted("lstm", window=5, hidden_units=4)
    start = 100
    history = X.iloc[start - history_rows:start] if history_rows else None
    rows = X.iloc[start:start + 12]
    streamer = model.streamer(history)
    streamed = np.array([streamer.update(rows.iloc[i]) for i in range(len(rows))])
    np.testing.assert_allclose(streamed, model.predict(rows, history=history), rtol=0, atol=1e-4)


def test_a_streamer_survives_a_pickled_model():
    import pickle

    model, X = _fitted("lstm", window=3, hidden_units=4)
    model.streamer(X.iloc[:10])  # builds the cached network
    loaded = pickle.loads(pickle.dumps(model))
    a = [model.streamer(X.iloc[:10]).update(X.iloc[10])]
    b = [loaded.streamer(X.iloc[:10]).update(X.iloc[10])]
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-6)
