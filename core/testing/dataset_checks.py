"""Contract checks for datasets: factories ``f(**params)`` that return a Recording."""

from __future__ import annotations

import numpy as np
import pandas as pd

from thermodrift.testing.estimator_checks import Factory


def _recording(factory: Factory, params: dict):
    from thermodrift.core.recording import Recording

    rec = factory(**params)
    assert isinstance(rec, Recording), f"factory returned {type(rec).__name__}, not a thermodrift Recording"
    return rec


def check_returns_recording(factory: Factory, params: dict) -> None:
    """The factory returns a Recording with temperature channels (°C) and something to model (displacement
    channels in µm, or a temperature target beside other inputs) on one time axis (s)."""
    rec = _recording(factory, params)
    time_s = np.asarray(rec.time_s, dtype=float)
    assert time_s.size >= 2 and np.all(np.diff(time_s) > 0), "time_s must have at least 2 strictly increasing samples"
    assert rec.displacements.shape[1] or len(rec.channels) >= 2, \
        "the recording has no displacement channel and no inputs beside its temperature to model it from"
    for role, frame in (("temperature", rec.temperatures), ("displacement", rec.displacements)):
        if role == "displacement" and not frame.shape[1]:
            continue
        assert isinstance(frame, pd.DataFrame) and frame.shape[1] >= 1, f"the recording has no {role} channel"
        assert len(frame) == time_s.size, f"{role} frame has {len(frame)} rows for {time_s.size} time stamps"
        assert all(pd.api.types.is_float_dtype(t) for t in frame.dtypes), f"{role} channels must be float"
        empty = [c for c in frame.columns if frame[c].isna().all()]
        assert not empty, f"{role} channels without a single value: {empty}"


def check_dataset_deterministic(factory: Factory, params: dict) -> None:
    """Two calls with the same parameters return the same data (simulated datasets take a seed)."""
    first, second = _recording(factory, params), _recording(factory, params)
    pd.testing.assert_frame_equal(first.data, second.data, obj="recording data of two identical calls")


DATASET_CHECKS = (check_returns_recording, check_dataset_deterministic)
