"""A compensator package on disk: data only, never a pickle.

``package.json`` holds one JSON tree; numpy arrays in it are references into ``arrays.npz`` (read with
``allow_pickle=False``) and torch tensors (networks only) references into ``weights.pt`` (read with
``torch.load(weights_only=True)``). Non-finite floats are written as ``{"$float": "nan"}`` (JSON has none).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

FORMAT = "thermodrift-compensator/1"
DOC, ARRAYS, WEIGHTS = "package.json", "arrays.npz", "weights.pt"


class PackageError(ValueError):
    """A folder that is not a readable compensator package; the message names the file and what to do."""


def write(doc: dict[str, Any], folder: str | Path) -> Path:
    """Write ``doc`` (a JSON-able tree whose leaves may be numpy arrays or torch tensors) into ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {}
    tensors: dict[str, Any] = {}

    def encode(value: Any) -> Any:
        if isinstance(value, dict):
            return {str(k): encode(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [encode(v) for v in value]
        if isinstance(value, np.ndarray):
            if value.dtype == object:
                return [encode(v) for v in value.tolist()]
            key = f"a{len(arrays)}"
            arrays[key] = value
            return {"$array": key}
        if type(value).__module__.startswith("torch") and hasattr(value, "detach"):
            key = f"t{len(tensors)}"
            tensors[key] = value.detach().cpu().clone()
            return {"$tensor": key}
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        if isinstance(value, (int, np.integer)):
            return int(value)
        if isinstance(value, (float, np.floating)):
            v = float(value)
            return v if np.isfinite(v) else {"$float": repr(v)}
        if value is None or isinstance(value, str):
            return value
        raise TypeError(f"a compensator package holds data only; cannot store a {type(value).__name__}")

    tree = {"format": FORMAT, **encode(doc)}
    (folder / DOC).write_text(json.dumps(tree, indent=1), encoding="utf-8")
    np.savez(folder / ARRAYS, **arrays)
    if tensors:
        import torch

        torch.save(tensors, folder / WEIGHTS)
    return folder


def read(folder: str | Path) -> dict[str, Any]:
    """The tree written by :func:`write`, arrays and tensors restored; :class:`PackageError` on a bad folder."""
    folder = Path(folder)
    path = folder / DOC
    if not path.is_file():
        raise PackageError(f"{folder}: no {DOC}; pass the folder that `thermodrift export` wrote")
    try:
        tree = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PackageError(f"{path}: unreadable ({type(exc).__name__}); export the run again") from None
    if tree.get("format") != FORMAT:
        raise PackageError(f"{path}: format {tree.get('format')!r}, expected {FORMAT!r}; export the run again "
                           "with this version")
    with np.load(folder / ARRAYS, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    tensors: dict[str, Any] = {}
    if (folder / WEIGHTS).is_file():
        import torch

        tensors = torch.load(folder / WEIGHTS, weights_only=True)

    def decode(value: Any) -> Any:
        if isinstance(value, list):
            return [decode(v) for v in value]
        if isinstance(value, dict):
            if "$array" in value:
                return arrays[value["$array"]]
            if "$tensor" in value:
                return tensors[value["$tensor"]]
            if "$float" in value:
                return float(value["$float"])
            return {k: decode(v) for k, v in value.items()}
        return value

    return decode(tree)


def document(model_state: dict[str, Any], limits: dict[str, Any], *, fallbacks: dict[str, Any] | None = None,
             axes: dict[str, dict[str, Any]] | None = None, versions: dict[str, str] | None = None,
             source: dict[str, Any] | None = None) -> dict[str, Any]:
    """The tree a package holds: the model's exported state, the training ``limits`` (per input and target),
    the safety defaults derived from them, fallbacks (sensor -> {"state", "warmup_rows"}), target axes, probe
    filter defaults, versions and where it came from."""
    from thermodrift.compensator import limits as limits_mod
    from thermodrift.compensator import probe

    missing = [c for c in model_state["inputs"] if c not in limits["inputs"]]
    if missing:
        raise PackageError(f"the training limits name no range for inputs {missing}")
    return {"model": model_state, "limits": limits, "safety": limits_mod.safety_defaults(limits),
            "sampling_interval_s": limits["sampling_interval_s"], "fallbacks": fallbacks or {},
            "axes": axes or {}, "probe": {"noise_um": probe.PROBE_NOISE_UM,
                                          "drift_um_per_sqrt_h": probe.BIAS_DRIFT_UM_PER_SQRT_H,
                                          "initial_um": probe.INITIAL_UM},
            "versions": versions or {}, "source": source or {}}
