"""The windowed torch models share one base (plugins/models/_sequence.py): windows, history and a streamer that
keeps its window incrementally. S3's sequence models: windows over past inputs, history and streaming, DLTK's
ablations, and that they learn."""

import numpy as np
import pytest

from thermodrift.core import registry
from thermodrift.plugins.models import lstm as lstm_module
from thermodrift.plugins.models._sequence import SequenceModel, SequenceStreamer, windows
from thermodrift.plugins.models.dltk import ABLATIONS, DLTK
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


S3_MODELS = ["cnn_lstm", "ma_cnn", "cnn_lstm_transformer", "tcn_lstm", "dltk"]
S3_TINY = dict(window=6, trainer=dict(epochs=6, t0=2, batch_size=64, device="cpu"))
SMALL = {"cnn_lstm": dict(channels=4, hidden_size=8), "ma_cnn": dict(channels=6),
         "cnn_lstm_transformer": dict(channels=4, hidden_size=8, heads=2), "tcn_lstm": dict(channels=4, hidden_size=8),
         "dltk": dict(channels=4, hidden_size=8, heads=2, kan_grid=2)}


@pytest.mark.usefixtures("one_torch_thread")  # tiny networks run fastest on one thread
def test_windows_hold_the_past_rows_and_repeat_the_first():
    x = np.arange(10.0).reshape(5, 2)
    w = windows(x, 3)
    assert w.shape == (5, 3, 2)
    assert np.array_equal(w[4], x[2:5]) and np.array_equal(w[0], x[[0, 0, 0]]) and np.array_equal(w[1], x[[0, 0, 1]])


@pytest.mark.usefixtures("one_torch_thread")  # tiny networks run fastest on one thread
@pytest.mark.parametrize("name", S3_MODELS)
def test_history_and_streaming_equal_the_batch_prediction(name):
    X, y = tiny_frames()
    y = y[["disp_z_um"]]
    model = registry.create("model", name, **SMALL[name], **S3_TINY).fit(X[:200], y[:200])
    assert model.history_length == 5
    whole = model.predict(X)
    with_history = model.predict(X[250:], history=X[:250])
    assert np.allclose(with_history, whole[250:], atol=1e-6)
    other = model.predict(X[250:], history=X[:250] + 3.0)  # another past changes only the first window - 1 rows
    assert np.abs(other[:5] - whole[250:255]).max() > 1e-6 and np.allclose(other[5:], whole[255:], atol=1e-6)
    streamer = model.streamer(X[:250])
    streamed = np.array([streamer.update(row) for row in X[250:270].to_dict("records")])
    assert np.allclose(streamed, whole[250:270], atol=1e-4)


@pytest.mark.usefixtures("one_torch_thread")  # tiny networks run fastest on one thread
def test_the_five_ablations_are_five_different_networks():
    X, y = tiny_frames()
    counts = {}
    for tag, switches in ABLATIONS.items():
        model = DLTK(**SMALL["dltk"], **S3_TINY, **switches).fit(X, y)
        counts[tag] = model.n_parameters()
    assert len(set(counts.values())) == 5, counts
    assert all(counts["full"] > counts[tag] for tag in ABLATIONS if tag != "full"), counts


@pytest.mark.usefixtures("one_torch_thread")  # tiny networks run fastest on one thread
def test_the_deformable_convolution_starts_as_a_plain_convolution_and_learns_offsets():
    import torch

    from thermodrift.plugins.models._sequence import layers

    L = layers()
    torch.manual_seed(0)
    deform = L["DeformableConv1d"](3, 5, 3)
    plain = L["Conv"](3, 5, 3)
    plain.conv.weight.data.copy_(deform.weight.data)
    plain.conv.bias.data.copy_(deform.bias.data)
    x = torch.randn(4, 7, 3)
    assert torch.allclose(deform(x), plain(x), atol=1e-5)  # zero offsets = an ordinary 'same' convolution
    deform(x).pow(2).sum().backward()
    assert deform.offset.weight.grad.abs().sum() > 0  # offsets receive gradient through the interpolation


@pytest.mark.usefixtures("one_torch_thread")  # tiny networks run fastest on one thread
def test_dltk_learns_the_drift():
    X, y = tiny_frames()
    y = y[["disp_z_um"]]
    model = DLTK(**SMALL["dltk"], window=6,
                 trainer=dict(epochs=60, t0=10, batch_size=32, lr_max=1e-2, patience=None, device="cpu"))
    rmse = np.sqrt(np.mean((model.fit(X, y).predict(X) - y.to_numpy()) ** 2))
    assert rmse < 0.3 * y.to_numpy().std(), (rmse, y.to_numpy().std())
