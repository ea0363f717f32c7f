"""Contract checks for thermal models (``thermodrift.core.components.ThermalModel``), run on the tiny recording.

Models get their inputs exactly as a study builds them (``thermodrift.core.study.model_inputs``): the
temperatures, the channels of their ``extra_input_roles`` and, where they use it, the target history.
"""

from __future__ import annotations

import numpy as np
import optuna
import pandas as pd

from thermodrift.core.errors import InputError
from thermodrift.core.metrics import rms, rmse
from thermodrift.core.registry import build
from thermodrift.core.search_space import distributions, suggest
from thermodrift.testing import _optuna
from thermodrift.core.study import model_inputs
from thermodrift.testing.data import tiny_frames, tiny_recording
from thermodrift.testing.estimator_checks import SHARED_CHECKS, Factory, fitted_attributes, pickled, seeded

SEARCH_SPACE_POINTS = 3
# Predictions must be within a decade of the targets' RMS per channel: catches mm-for-µm and divergence.
MAGNITUDE_BAND = (0.1, 10.0)


def _inputs(model, X: pd.DataFrame, y: pd.DataFrame) -> pd.DataFrame:
    """``X`` as the study would pass it to this model (plus extra-role and target-history columns)."""
    return model_inputs(tiny_recording(), list(X.columns), type(model), list(y.columns)).loc[X.index]


def _fit_predict(model, X: pd.DataFrame, y: pd.DataFrame) -> np.ndarray:
    Xm = _inputs(model, X, y)
    return model.fit(Xm, y).predict(Xm)


def check_fit_predict_shape(factory: Factory, params: dict) -> None:
    """``fit`` returns self; ``predict`` gives (n, k) for k displacement channels, for k = 2 and k = 1."""
    X, y = tiny_frames()
    for targets in (y, y[[y.columns[0]]]):
        model = seeded(factory(**params))
        Xm = _inputs(model, X, targets)
        assert model.fit(Xm, targets) is model, "fit() must return self"
        assert fitted_attributes(model), "fit() set no fitted attributes (names ending in '_')"
        k = targets.shape[1]
        pred = np.asarray(model.predict(Xm))
        assert pred.shape == (len(X), k), f"predict() returned shape {pred.shape} for {len(X)} samples x {k} channels"
        part = np.asarray(model.predict(Xm.iloc[-50:]))
        assert part.shape == (50, k), f"predict() on 50 samples returned shape {part.shape}"


def check_predictions_in_um(factory: Factory, params: dict) -> None:
    """Predictions are finite and, per channel, within a decade of the targets' RMS (µm, not mm or diverged)."""
    X, y = tiny_frames()
    pred = _fit_predict(seeded(factory(**params)), X, y)
    assert np.isfinite(pred).all(), f"{int((~np.isfinite(pred)).sum())} non-finite predictions"
    target_rms = rms(y.to_numpy(), axis=0)
    pred_rms = rms(pred, axis=0)
    low, high = MAGNITUDE_BAND
    for channel, t, p in zip(y.columns, target_rms, pred_rms):
        assert low * t <= p <= high * t, (
            f"{channel}: prediction RMS {p:.3g} µm vs target RMS {t:.3g} µm on the training data; "
            "predictions must be in µm and of the targets' order")


def check_model_deterministic(factory: Factory, params: dict) -> None:
    """Two fits with the same parameters (``random_state=0`` where there is one) predict the same."""
    X, y = tiny_frames()
    first = _fit_predict(seeded(factory(**params)), X, y)
    second = _fit_predict(seeded(factory(**params)), X, y)
    assert np.allclose(first, second, rtol=1e-6, atol=1e-6), (
        f"two fits with the same seed differ by up to {np.nanmax(np.abs(first - second)):.3g} µm; "
        "seed every random source from a random_state parameter")


def check_model_pickle(factory: Factory, params: dict) -> None:
    """A fitted model predicts the same after a pickle round trip."""
    X, y = tiny_frames()
    model = seeded(factory(**params))
    Xm = _inputs(model, X, y)
    before = model.fit(Xm, y).predict(Xm)
    after = pickled(model).predict(Xm)
    assert np.allclose(before, after, rtol=1e-9, atol=1e-9), "predictions changed after a pickle round trip"


def check_search_space(factory: Factory, params: dict) -> None:
    """``search_space()`` is well formed, names constructor parameters, and every sampled point fits."""
    model = factory(**params)
    space = type(model).search_space()
    assert isinstance(space, dict), f"search_space() must return a dict, got {type(space).__name__}"
    unknown = sorted(set(space) - set(model.get_params(deep=True)))
    assert not unknown, f"search_space() names {unknown}, which are not constructor parameters"
    try:
        distributions(space)
    except InputError as exc:
        raise AssertionError(f"malformed search_space(): {exc}") from None
    if not space:
        return
    X, y = tiny_frames()
    with _optuna.quiet():
        study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
        for _ in range(SEARCH_SPACE_POINTS):
            trial = study.ask()
            point = suggest(trial, space)
            try:
                pred = _fit_predict(seeded(build(factory, {**params, **point})), X, y)
            except Exception as exc:
                raise AssertionError(f"search-space point {point} failed: {type(exc).__name__}: {exc}") from exc
            assert np.isfinite(pred).all(), f"search-space point {point} gives non-finite predictions"
            study.tell(trial, float(rmse(pred, y.to_numpy())))


STREAM_TOLERANCE_UM = 1e-4
STREAM_ROWS = 25


def check_streaming_equals_batch(factory: Factory, params: dict) -> None:
    """``streamer(history).update(row)`` over consecutive rows equals ``predict(rows, history)`` within
    1e-4 µm, with history and without (the contract of ``ThermalModel``, as a controller calls a model)."""
    X, y = tiny_frames()
    model = seeded(factory(**params))
    Xm = _inputs(model, X, y)
    model.fit(Xm, y)
    cut = len(Xm) // 2
    for history in (Xm.iloc[:cut], None):
        rows = Xm.iloc[cut:cut + STREAM_ROWS] if history is not None else Xm.iloc[:STREAM_ROWS]
        batch = np.asarray(model.predict(rows, history=history), dtype=float)
        streamer = model.streamer(history)
        streamed = np.array([np.asarray(streamer.update(rows.iloc[i]), dtype=float).reshape(-1)
                             for i in range(len(rows))])
        assert streamed.shape == batch.shape, f"streamed shape {streamed.shape} != batch shape {batch.shape}"
        worst = float(np.abs(streamed - batch).max())
        assert worst <= STREAM_TOLERANCE_UM, (
            f"streaming one row at a time differs from predict(rows, history) by up to {worst:.3g} µm "
            f"({'with' if history is not None else 'without'} history); carry the state the batch uses")


def check_export_equals_predict(factory: Factory, params: dict) -> None:
    """A model that exports (its ``export_state()`` does not raise ``NotImplementedError``) gives a data-only
    state (it survives a package's write and read) whose compensator runtime, fed one row at a time after the
    history, equals ``predict(rows, history)`` within 1e-4 µm: what a controller runs is what was evaluated."""
    import tempfile

    from thermodrift.compensator import package, runtime

    X, y = tiny_frames()
    model = seeded(factory(**params))
    Xm = _inputs(model, X, y)
    model.fit(Xm, y)
    try:
        state = model.export_state()
    except NotImplementedError:
        return  # the model does not export: nothing runs on a controller
    with tempfile.TemporaryDirectory() as folder:
        state = package.read(package.write({"model": state}, folder))["model"]
    rt = runtime.build(state)
    cut = len(Xm) // 2
    history, rows = Xm.iloc[:cut], Xm.iloc[cut:cut + STREAM_ROWS]
    batch = np.asarray(model.predict(rows, history=history), dtype=float)
    cols = list(rt.inputs)
    stream = rt.streamer(history[cols].to_numpy(dtype=float), history.index.to_numpy(dtype=float))
    streamed = np.array([np.asarray(stream.update(rows[cols].iloc[i].to_numpy(dtype=float), float(rows.index[i])),
                                    dtype=float) for i in range(len(rows))])
    worst = float(np.abs(streamed - batch).max())
    assert worst <= STREAM_TOLERANCE_UM, (
        f"runtime {state.get('runtime')!r} streaming the exported state differs from predict(rows, history) by up "
        f"to {worst:.3g} µm; export what predict uses")


HISTORY_TOLERANCE_UM = 1e-4  # float32 models included (architecture: "Models as a controller uses them")
HISTORY_CUT, STREAM_ROWS = 200, 12


def check_history_consistent(factory: Factory, params: dict) -> None:
    """For a model with history (``history_length != 0``): predicting a slice with the input rows before it as
    ``history`` equals predicting the whole and slicing, and ``streamer(history).update(row)`` row by row equals
    both (within 1e-4 µm). Memoryless models pass without a fit."""
    model = seeded(factory(**params))
    if getattr(model, "history_length", 0) == 0:
        return
    X, y = tiny_frames()
    Xm = _inputs(model, X, y)
    whole = np.asarray(model.fit(Xm, y).predict(Xm))
    part = np.asarray(model.predict(Xm.iloc[HISTORY_CUT:], history=Xm.iloc[:HISTORY_CUT]))
    gap = float(np.max(np.abs(part - whole[HISTORY_CUT:])))
    assert gap <= HISTORY_TOLERANCE_UM, (
        f"predict(X[{HISTORY_CUT}:], history=X[:{HISTORY_CUT}]) differs from predict(X)[{HISTORY_CUT}:] by up to "
        f"{gap:.3g} µm; a prediction must depend only on the rows before it (history) and the rows themselves")
    stream = model.streamer(Xm.iloc[:HISTORY_CUT])
    rows = [row for _, row in Xm.iloc[HISTORY_CUT:HISTORY_CUT + STREAM_ROWS].iterrows()]  # Series named by time (s)
    streamed = np.array([np.asarray(stream.update(r), dtype=float).ravel() for r in rows])
    gap = float(np.max(np.abs(streamed - whole[HISTORY_CUT:HISTORY_CUT + STREAM_ROWS])))
    assert gap <= HISTORY_TOLERANCE_UM, (
        f"streamer(history).update(row) differs from the batch prediction by up to {gap:.3g} µm")


MODEL_CHECKS = (*SHARED_CHECKS, check_fit_predict_shape, check_predictions_in_um, check_model_deterministic,
                check_model_pickle, check_search_space, check_streaming_equals_batch,
                check_history_consistent, check_export_equals_predict)
