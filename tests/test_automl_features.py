"""The feature stage (compensator/features.py): filters, drive terms, history, streaming and state round trip."""

import json

import numpy as np
import pytest

from thermodrift.compensator.features import FeatureStage


def _stage(taus=(60.0, 600.0), powers=(1.0, 2.0)):
    rng = np.random.default_rng(0)
    n = 200
    temps = 20 + np.cumsum(rng.normal(0, 0.1, (n, 2)), axis=0)
    speed = np.repeat([0.0, 3000.0, 6000.0, 0.0], n // 4)[:, None]
    values = np.hstack([temps, speed])
    stage = FeatureStage.fit(values, ["T1", "T2", "rpm"], {"T1": "temperature", "T2": "temperature",
                                                           "rpm": "speed"}, np.arange(n) * 15.0, taus, powers)
    return stage, values


def test_filter_is_the_exact_first_order_discretisation():
    stage, values = _stage(taus=(600.0,), powers=(1.0,))
    F = stage.transform(values)
    assert stage.names == ["T1", "T2", "rpm^1", "T1|f600s", "T2|f600s", "rpm^1|f600s"]
    a = np.exp(-15.0 / 600.0)
    x = values[0, 0]
    for i in range(len(values)):  # the temperature filter starts at the first reading
        x = a * x + (1 - a) * values[i, 0]
        assert F[i, 3] == pytest.approx(x, abs=1e-12)
    u = values[:, 2] / 6000.0  # the drive term: |v| / v_ref, its filter from rest
    d = 0.0
    for i in range(len(values)):
        d = a * d + (1 - a) * u[i]
    assert F[-1, 5] == pytest.approx(d, abs=1e-12)
    assert F[:, 2].max() == pytest.approx(1.0)


def test_history_and_streaming_equal_the_batch():
    stage, values = _stage()
    whole = stage.transform(values)
    assert np.allclose(stage.transform(values[120:], history=values[:120]), whole[120:], atol=1e-12)
    for history in (values[:120], None):
        start = 0 if history is None else 120
        stream = stage.stream(history)
        streamed = np.array([stream.update(values[i]) for i in range(start, start + 40)])
        assert np.allclose(streamed, whole[start:start + 40], atol=1e-12)


def test_state_round_trips_through_json():
    stage, values = _stage()
    state = stage.to_state()
    text = json.dumps({k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in state.items()})
    back = FeatureStage.from_state(json.loads(text))
    assert back == stage
    assert np.array_equal(back.transform(values), stage.transform(values))
    with pytest.raises(ValueError, match="format"):
        FeatureStage.from_state({"format": "other"})


def test_wrong_column_count_is_refused():
    stage, values = _stage()
    with pytest.raises(ValueError, match="reads 3 columns"):
        stage.transform(values[:, :2])
