"""S3's sequence models: windows over past inputs, history and streaming, DLTK's ablations, and that they learn."""

from __future__ import annotations

import numpy as np
import pytest

from thermodrift.core import registry
from thermodrift.plugins.models._sequence import windows
from thermodrift.plugins.models.dltk import ABLATIONS, DLTK
from thermodrift.testing.data import tiny_frames

pytestmark = pytest.mark.usefixtures("one_torch_thread")
S3_MODELS = ["cnn_lstm", "ma_cnn", "cnn_lstm_transformer", "tcn_lstm", "dltk"]
TINY = dict(window=6, trainer=dict(epochs=6, t0=2, batch_size=64, device="cpu"))
SMALL = {"cnn_lstm": dict(channels=4, hidden_size=8), "ma_cnn": dict(channels=6),
         "cnn_lstm_transformer": dict(channels=4, hidden_size=8, heads=2), "tcn_lstm": dict(channels=4, hidden_size=8),
         "dltk": dict(channels=4, hidden_size=8, heads=2, kan_grid=2)}


def test_windows_hold_the_past_rows_and_repeat_the_first():
    x = np.arange(10.0).reshape(5, 2)
    w = windows(x, 3)
    assert w.shape == (5, 3, 2)
    assert np.array_equal(w[4], x[2:5]) and np.array_equal(w[0], x[[0, 0, 0]]) and np.array_equal(w[1], x[[0, 0, 1]])


@pytest.mark.parametrize("name", S3_MODELS)
def test_history_and_streaming_equal_the_batch_prediction(name):
    X, y = tiny_frames()
    y = y[["disp_z_um"]]
    model = registry.create("model", name, **SMALL[name], **TINY).fit(X[:200], y[:200])
    assert model.history_length == 5
    whole = model.predict(X)
    with_history = model.predict(X[250:], history=X[:250])
    assert np.allclose(with_history, whole[250:], atol=1e-6)
    other = model.predict(X[250:], history=X[:250] + 3.0)  # another past changes only the first window - 1 rows
    assert np.abs(other[:5] - whole[250:255]).max() > 1e-6 and np.allclose(other[5:], whole[255:], atol=1e-6)
    streamer = model.streamer(X[:250])
    streamed = np.array([streamer.update(row) for row in X[250:270].to_dict("records")])
    assert np.allclose(streamed, whole[250:270], atol=1e-4)


def test_the_five_ablations_are_five_different_networks():
    X, y = tiny_frames()
    counts = {}
    for tag, switches in ABLATIONS.items():
        model = DLTK(**SMALL["dltk"], **TINY, **switches).fit(X, y)
        counts[tag] = model.n_parameters()
    assert len(set(counts.values())) == 5, counts
    assert all(counts["full"] > counts[tag] for tag in ABLATIONS if tag != "full"), counts


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


def test_dltk_learns_the_drift():
    X, y = tiny_frames()
    y = y[["disp_z_um"]]
    model = DLTK(**SMALL["dltk"], window=6,
                 trainer=dict(epochs=60, t0=10, batch_size=32, lr_max=1e-2, patience=None, device="cpu"))
    rmse = np.sqrt(np.mean((model.fit(X, y).predict(X) - y.to_numpy()) ** 2))
    assert rmse < 0.3 * y.to_numpy().std(), (rmse, y.to_numpy().std())
