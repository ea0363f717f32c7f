"""The compensator runtime: every exportable family streams from its data-only package exactly as the training
side predicts with history, and the runtime imports nothing of the training stack."""

import json
import subprocess
import sys

import numpy as np
import pytest

from thermodrift import compensator
from thermodrift.compensator import limits, package
from thermodrift.core import registry
from thermodrift.core.study import model_inputs
from thermodrift.testing.data import tiny_recording

CUT = 200  # training rows; the rest are streamed after them as history


def fitted(name: str, params: dict | None = None):
    rec = tiny_recording(seed=0)
    targets, temps = rec.columns("displacement"), rec.columns("temperature")
    cls = registry.get("model", name).factory
    model = registry.create("model", name, **(params if params is not None else cls.get_test_params()[0]))
    X, y = model_inputs(rec, temps, cls, targets), rec.data[targets]
    model.fit(X.iloc[:CUT], y.iloc[:CUT])
    return model, X, y


def export(model, X, y, folder, fallbacks=None):
    lim = limits.training_limits(X.iloc[:CUT].to_numpy(), list(X.columns), y.iloc[:CUT].to_numpy(),
                                 list(y.columns), X.index[:CUT].to_numpy())
    package.write(package.document(model.export_state(), lim, fallbacks=fallbacks), folder)
    return compensator.load(folder)


def _exporting() -> list[str]:
    """Every registered model whose class exports (overrides ``ThermalModel.export_state``)."""
    from thermodrift.core.components import ThermalModel

    return [n for n in registry.names("model")
            if getattr(registry.get("model", n).factory, "export_state", None) is not ThermalModel.export_state]


@pytest.mark.parametrize("name", _exporting())
def test_streaming_from_the_package_equals_predict_with_history(name, tmp_path, one_torch_thread):
    model, X, y = fitted(name)
    pkg = export(model, X, y, tmp_path / name)
    tol = 1e-4 if pkg.model_state["runtime"] == "sequence" else 1e-9  # float32 networks
    history, rows = X.iloc[:CUT], X.iloc[CUT:]
    expected = model.predict(rows, history=history)
    for guarded in (False, True):  # the bare streamer, and the compensator with limits off
        if guarded:
            comp = pkg.compensator(limits=False, history=history[pkg.inputs].to_numpy(),
                                   history_times_s=history.index.to_numpy())
            got = np.array([comp.update(t, v).written for t, v in zip(rows.index, rows[pkg.inputs].to_numpy())])
        else:
            s = pkg.streamer(history[pkg.inputs].to_numpy(), history.index.to_numpy())
            got = np.array([s.update(v, t) for t, v in zip(rows.index, rows[pkg.inputs].to_numpy())])
        assert np.abs(got - expected).max() <= tol


def test_package_is_data_only_and_states_its_limits(tmp_path):
    model, X, y = fitted("mlr")
    export(model, X, y, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arrays.npz", "package.json"]
    doc = json.loads((tmp_path / "package.json").read_text())
    assert doc["format"] == package.FORMAT and doc["model"]["runtime"] == "linear"
    lim = doc["limits"]["inputs"]["T_front_bearing"]
    col = X["T_front_bearing"].iloc[:CUT]
    assert lim["min"] == col.min() and lim["max"] == col.max()
    assert lim["max_step"] == pytest.approx(np.abs(np.diff(col)).max())
    assert set(doc["safety"]["max_step_um"]) == set(doc["safety"]["clamp_um"]) == set(y.columns)
    np.load(tmp_path / "arrays.npz", allow_pickle=False)  # no object arrays


def test_models_without_an_export_say_so():
    model, _, _ = fitted("mnr")
    with pytest.raises(NotImplementedError, match="model MNR.* cannot be exported"):
        model.export_state()


ISOLATION = """
import sys, numpy as np
import thermodrift.compensator as c
pkg = c.load(sys.argv[1])
s = pkg.compensator()
s.update(0.0, np.zeros(len(pkg.inputs)) + 20.0)
bad = sorted(m for m in sys.modules if m.split('.')[0] in ('mlflow', 'optuna', 'sklearn', 'pandas', 'torch', 'scipy')
             or m.startswith(('thermodrift.core', 'thermodrift.plugins')))
print(' '.join(bad))
"""


@pytest.mark.parametrize("name, allowed", [("mlr", set()), ("transfer_function", set()), ("lptn", {"scipy"}),
                                           ("lstm", {"torch"}), ("bp", {"torch"})])
def test_runtime_imports_no_training_stack(name, allowed, tmp_path, one_torch_thread):
    model, X, y = fitted(name)
    export(model, X, y, tmp_path)
    out = subprocess.run([sys.executable, "-c", ISOLATION, str(tmp_path)], capture_output=True, text=True,
                         check=True).stdout.split()
    assert {m.split(".")[0] for m in out} <= allowed, out


def test_pipeline_and_ensemble_runtimes_follow_the_export_contract():
    """A pipeline state (selected inputs → feature stage → inner model) and an ensemble of two stream as their
    parts predict in batch."""
    import pandas as pd

    from thermodrift.compensator import runtime
    from thermodrift.compensator.features import FeatureStage

    rec = tiny_recording(seed=0)
    targets = rec.columns("displacement")
    inputs = rec.columns("temperature") + rec.columns("speed")
    X, y = rec.data[inputs], rec.data[targets]
    states, preds = [], []
    for selected, taus in ((inputs, (600.0, 3600.0)), (inputs[:2] + rec.columns("speed"), (1200.0,))):
        stage = FeatureStage.fit(X[selected].to_numpy(), selected, {c: rec.channels[c].role for c in selected},
                                 X.index.to_numpy(), taus, (1.0, 2.0))
        F = pd.DataFrame(stage.transform(X[selected].to_numpy()), columns=stage.names, index=X.index)
        inner = registry.create("model", "mlr", alpha=1.0).fit(F.iloc[:CUT], y.iloc[:CUT])
        states.append({"runtime": "pipeline", "inputs": inputs, "targets": targets, "history_length": None,
                       "selected": selected, "features": stage.to_state(), "model": inner.export_state()})
        preds.append(inner.predict(F))
    ensemble = {"runtime": "ensemble", "inputs": inputs, "targets": targets, "history_length": None,
                "weights": [0.25, 0.75], "members": states}
    for state, expected in ((states[0], preds[0]), (states[1], preds[1]),
                            (ensemble, 0.25 * preds[0] + 0.75 * preds[1])):
        rt = runtime.build(state)
        hist = X.to_numpy()[:CUT]
        s = rt.streamer(hist, X.index.to_numpy()[:CUT])
        got = np.array([s.update(v, t) for t, v in zip(X.index[CUT:], X.to_numpy()[CUT:])])
        assert np.abs(got - expected[CUT:]).max() <= 1e-9
