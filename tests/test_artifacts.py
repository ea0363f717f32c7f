"""Logged models are data only: every registered model round-trips exactly, loads as an MLflow pyfunc model,
and a stored model naming an untrusted class is refused without running it."""

import json

import mlflow
import mlflow.pyfunc
import numpy as np
import pytest

from thermodrift.core import artifacts, registry
from thermodrift.core.errors import InputError
from thermodrift.core.study import model_inputs
from thermodrift.testing.data import tiny_recording


def _fitted(name):
    rec = tiny_recording(seed=0)
    targets, cls = rec.columns("displacement"), registry.get("model", name).factory
    params = cls.get_test_params()[0] if hasattr(cls, "get_test_params") else {}
    X = model_inputs(rec, rec.columns("temperature"), cls, targets)
    return registry.create("model", name, **params).fit(X, rec.data[targets]), X


@pytest.mark.parametrize("name", registry.names("model"))
def test_every_registered_model_round_trips_exactly(tmp_path, name):
    model, X = _fitted(name)
    before = model.predict(X)  # as in a job, which predicts before it logs the model (caches built here stay out)
    artifacts.save(model, name, tmp_path)
    loaded = artifacts.load(tmp_path)
    assert type(loaded) is type(model) and loaded.get_params() == model.get_params()
    np.testing.assert_array_equal(loaded.predict(X), before)


def test_logged_model_loads_as_pyfunc_and_predicts_as_before(tmp_path):
    model, X = _fitted("bp")
    mlflow.set_tracking_uri(f"sqlite:///{tmp_path / 'mlflow.db'}")
    mlflow.create_experiment("artifacts", artifact_location=(tmp_path / "mlruns").as_uri())
    mlflow.set_experiment("artifacts")
    with mlflow.start_run():
        artifacts.log_model(model, "bp")
    (logged,) = mlflow.search_logged_models(output_format="list")
    loaded = mlflow.pyfunc.load_model(f"models:/{logged.model_id}")
    np.testing.assert_array_equal(np.asarray(loaded.predict(X)), model.predict(X))
    stored = [p.name for p in (tmp_path / "mlruns").rglob("*") if p.is_file() and "thermodrift_model" in str(p)]
    assert sorted(stored) == ["arrays.npz", "model.json", "tensors.pt"]  # no pickle of the model


def test_a_stored_model_naming_an_untrusted_class_is_refused(tmp_path):
    model, _ = _fitted("mlr")
    artifacts.save(model, "mlr", tmp_path)
    doc = json.loads((tmp_path / "model.json").read_text())
    doc["state"]["__dict__"]["regressor_"] = {"__object__": "subprocess:Popen", "state": {"__dict__": {}}}
    (tmp_path / "model.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match="subprocess:Popen.*not trusted"):
        artifacts.load(tmp_path)
