"""Logged models that load without running code from the artifact.

A pickled model (cloudpickle, joblib) runs whatever the file says when it is loaded, so a model from an
untrusted run could take over the machine. Here a fitted model is written as data only: ``model.json`` (the
registry name, the constructor parameters and the fitted state as a JSON tree), ``arrays.npz`` (numpy arrays,
read with ``allow_pickle=False``) and ``tensors.pt`` (torch tensors, read with ``torch.load(weights_only=True)``).
Loading rebuilds the model through the registry by name and parameters, then restores the fitted state; nested
objects (a Ridge inside MLR, a scaler dataclass) are rebuilt only for trusted classes: thermodrift's own and
scikit-learn's. It is an MLflow ``pyfunc`` model (this module is its ``loader_module``), so
``mlflow.pyfunc.load_model(uri).predict(X)`` works as before.

Written by hand because skops (the scikit-learn answer) stores neither torch tensors nor plugin classes it
does not know, and MLflow's own flavours pickle.
"""

from __future__ import annotations

import importlib
import json
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from thermodrift.core.errors import InputError

FORMAT = "thermodrift-model/1"
TRUSTED_PREFIXES = ("thermodrift.", "sklearn.")


class _Writer:
    def __init__(self):
        self.arrays: dict[str, np.ndarray] = {}
        self.tensors: dict[str, Any] = {}

    def encode(self, value: Any) -> Any:
        if value is None or isinstance(value, (bool, str)):
            return value
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            return int(value)
        if isinstance(value, (float, np.floating)):
            return {"__float__": repr(float(value))}  # nan and inf survive JSON
        if isinstance(value, np.bool_):
            return bool(value)
        if isinstance(value, np.ndarray):
            if value.dtype == object:
                return {"__object_array__": [self.encode(v) for v in value.tolist()], "shape": list(value.shape)}
            key = f"a{len(self.arrays)}"
            self.arrays[key] = value
            return {"__array__": key}
        if isinstance(value, pd.DataFrame):
            return {"__frame__": [self.encode(list(value.columns)), self.encode(value.index),
                                  [self.encode(value[c].to_numpy()) for c in value.columns], self.encode(value.attrs)]}
        if isinstance(value, pd.Series):
            return {"__series__": [self.encode(value.name), self.encode(value.index), self.encode(value.to_numpy())]}
        if isinstance(value, pd.Index):
            return {"__index__": [self.encode(value.name), self.encode(value.to_numpy())]}
        if type(value).__module__ == "torch" and type(value).__name__ in ("Tensor", "Parameter"):
            key = f"t{len(self.tensors)}"
            self.tensors[key] = value.detach().cpu()
            return {"__tensor__": key}
        if isinstance(value, (list, tuple)):
            items = [self.encode(v) for v in value]
            return items if isinstance(value, list) else {"__tuple__": items}
        if isinstance(value, dict):
            if all(isinstance(k, str) for k in value):
                return {"__dict__": {k: self.encode(v) for k, v in value.items()}}
            return {"__items__": [[self.encode(k), self.encode(v)] for k, v in value.items()]}
        cls = type(value)
        name = f"{cls.__module__}:{cls.__qualname__}"
        if not cls.__module__.startswith(TRUSTED_PREFIXES) or not hasattr(value, "__dict__"):
            raise TypeError(f"cannot store a {name} safely")
        return {"__object__": name, "state": self.encode(dict(vars(value)))}


def save(model: Any, name: str, folder: str | Path) -> Path:
    """Write the fitted ``model`` (registry model ``name``) into ``folder`` as data only."""
    import torch

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    writer = _Writer()
    params = model.get_params(deep=False)
    # the pickling contract (__getstate__): what a class leaves out of pickles, such as a cache, stays out here
    state = {k: v for k, v in model.__getstate__().items() if k not in params}
    doc = {"format": FORMAT, "name": name, "params": writer.encode(params), "state": writer.encode(state)}
    (folder / "model.json").write_text(json.dumps(doc), encoding="utf-8")
    np.savez(folder / "arrays.npz", **writer.arrays)
    torch.save(writer.tensors, folder / "tensors.pt")
    return folder


class _Reader:
    def __init__(self, folder: Path):
        import torch

        with np.load(folder / "arrays.npz", allow_pickle=False) as npz:
            self.arrays = {k: npz[k] for k in npz.files}
        self.tensors = torch.load(folder / "tensors.pt", weights_only=True)

    def decode(self, value: Any) -> Any:
        if isinstance(value, list):
            return [self.decode(v) for v in value]
        if not isinstance(value, dict):
            return value
        if "__float__" in value:
            return float(value["__float__"])
        if "__array__" in value:
            return self.arrays[value["__array__"]]
        if "__tensor__" in value:
            return self.tensors[value["__tensor__"]]
        if "__object_array__" in value:
            out = np.empty(len(value["__object_array__"]), dtype=object)
            out[:] = [self.decode(v) for v in value["__object_array__"]]
            return out.reshape(value["shape"])
        if "__frame__" in value:
            columns, index, data, attrs = (self.decode(v) for v in value["__frame__"])
            frame = pd.DataFrame(dict(zip(range(len(columns)), data)), index=index).set_axis(columns, axis=1)
            frame.attrs.update(attrs)
            return frame
        if "__series__" in value:
            name, index, data = (self.decode(v) for v in value["__series__"])
            return pd.Series(data, index=index, name=name)
        if "__index__" in value:
            name, data = (self.decode(v) for v in value["__index__"])
            return pd.Index(data, name=name)
        if "__tuple__" in value:
            return tuple(self.decode(v) for v in value["__tuple__"])
        if "__dict__" in value:
            return {k: self.decode(v) for k, v in value["__dict__"].items()}
        if "__items__" in value:
            return {self.decode(k): self.decode(v) for k, v in value["__items__"]}
        if "__object__" in value:
            obj = object.__new__(_trusted_class(value["__object__"]))
            obj.__dict__.update(self.decode(value["state"]))
            return obj
        raise InputError(f"unknown entry in a stored model: {sorted(value)[:3]}")


def _trusted_class(name: str) -> type:
    module, _, qualname = name.partition(":")
    if not module.startswith(TRUSTED_PREFIXES):
        raise InputError(f"the stored model names class {name}, which is not trusted",
                         hint="only thermodrift and scikit-learn classes are rebuilt")
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    if not isinstance(obj, type):
        raise InputError(f"the stored model names {name}, which is not a class")
    return obj


def load(folder: str | Path) -> Any:
    """The fitted model in ``folder``, rebuilt through the registry; no code from the files runs."""
    from thermodrift.core import registry

    folder = Path(folder)
    doc = json.loads((folder / "model.json").read_text(encoding="utf-8"))
    if doc.get("format") != FORMAT:
        raise InputError(f"not a stored thermodrift model (format {doc.get('format')!r})", file=str(folder))
    reader = _Reader(folder)
    model = registry.create("model", doc["name"], **reader.decode(doc["params"]))
    vars(model).update(reader.decode(doc["state"]))
    return model


class _PyFunc:
    """What ``mlflow.pyfunc.load_model`` wraps: predict(DataFrame) -> array (µm)."""

    def __init__(self, model):
        self.model = model

    def predict(self, model_input, params=None):
        return self.model.predict(model_input)


def _load_pyfunc(data_path: str) -> _PyFunc:
    """MLflow's loader hook for ``loader_module=thermodrift.core.artifacts``."""
    return _PyFunc(load(data_path))


def log_model(model: Any, name: str) -> None:
    """Log the fitted ``model`` (registry model ``name``) into the active MLflow run as ``model``."""
    import mlflow.pyfunc

    with tempfile.TemporaryDirectory() as tmp:
        save(model, name, Path(tmp) / "thermodrift_model")
        mlflow.pyfunc.log_model(name="model", loader_module="thermodrift.core.artifacts",
                                data_path=str(Path(tmp) / "thermodrift_model"), pip_requirements=["thermodrift"])
