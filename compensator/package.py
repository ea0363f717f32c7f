"""A compensator package on disk: data only, never a pickle.

``package.json`` holds one JSON tree; numpy arrays in it are references into ``arrays.npz`` (read with
``allow_pickle=False``) and torch tensors (networks only) references into ``weights.pt`` (read with
``torch.load(weights_only=True)``). Non-finite floats are written as ``{"$float": "nan"}`` (JSON has none).
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from thermodrift.compensator.errors import PackageError

FORMAT = "thermodrift-compensator/1"
DOC, ARRAYS, WEIGHTS = "package.json", "arrays.npz", "weights.pt"

__all__ = ["ARRAYS", "DOC", "FORMAT", "PackageError", "WEIGHTS", "document", "read", "write"]


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


MAX_DEPTH = 64  # nesting of package.json; a package that `write` made is under 16 deep (pipelines of ensembles)


def read(folder: str | Path) -> dict[str, Any]:
    """The tree written by :func:`write`, arrays and tensors restored; :class:`PackageError` for anything else:
    not a JSON object of this format, nested deeper than :data:`MAX_DEPTH`, a reference to an array or tensor
    that is missing or not numeric, an unreadable or pickled ``arrays.npz``."""
    folder = Path(folder)
    path = folder / DOC
    if not path.is_file():
        raise PackageError(f"no {DOC}", file=str(folder), hint="pass the folder that `thermodrift export` wrote")
    try:
        tree = json.loads(path.read_text(encoding="utf-8"))
    except RecursionError:
        raise PackageError(f"nested deeper than {MAX_DEPTH} levels", file=str(path),
                           hint="not a package `thermodrift export` wrote; export the run again") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PackageError(f"unreadable ({type(exc).__name__})", file=str(path),
                           hint="export the run again") from None
    if not isinstance(tree, dict):
        raise PackageError(f"a JSON {type(tree).__name__}, not an object", file=str(path),
                           hint="export the run again")
    if tree.get("format") != FORMAT:
        raise PackageError(f"format {tree.get('format')!r}, expected {FORMAT!r}", file=str(path),
                           hint="export the run again with this version")
    _check_depth(tree, path)
    arrays = _arrays(folder / ARRAYS)
    tensors = _tensors(folder / WEIGHTS) if _refers(tree, "$tensor") else {}

    def decode(value: Any, where: str) -> Any:
        if isinstance(value, list):
            return [decode(v, f"{where}[{i}]") for i, v in enumerate(value)]
        if isinstance(value, dict):
            for marker, store, name in (("$array", arrays, ARRAYS), ("$tensor", tensors, WEIGHTS)):
                if marker in value:
                    key = value[marker]
                    if len(value) != 1 or not isinstance(key, str) or key not in store:
                        raise PackageError(f"entry {where} refers to {key!r}, which {name} does not hold",
                                           file=str(path), hint="export the run again")
                    return store[key]
            if "$float" in value:
                text = value["$float"]
                if len(value) != 1 or text not in ("nan", "inf", "-inf"):
                    raise PackageError(f"entry {where} is not a float ({text!r})", file=str(path),
                                       hint="export the run again")
                return float(text)
            return {k: decode(v, f"{where}.{k}" if where else k) for k, v in value.items()}
        return value

    return decode(tree, "")


def _check_depth(tree: Any, path: Path) -> None:
    """Refuse a tree nested deeper than :data:`MAX_DEPTH` (walked without recursion)."""
    todo = [(tree, 1)]
    while todo:
        value, depth = todo.pop()
        if depth > MAX_DEPTH:
            raise PackageError(f"nested deeper than {MAX_DEPTH} levels", file=str(path),
                               hint="not a package `thermodrift export` wrote; export the run again")
        children = value.values() if isinstance(value, dict) else value if isinstance(value, list) else ()
        todo += [(v, depth + 1) for v in children if isinstance(v, (dict, list))]


def _refers(tree: Any, marker: str) -> bool:
    if isinstance(tree, dict):
        return marker in tree or any(_refers(v, marker) for v in tree.values())
    return isinstance(tree, list) and any(_refers(v, marker) for v in tree)


def _arrays(path: Path) -> dict[str, np.ndarray]:
    """Every array of ``arrays.npz``, real numbers (or booleans) only, read without unpickling anything."""
    if not path.is_file():
        raise PackageError(f"no {ARRAYS}", file=str(path.parent), hint="copy the whole folder that "
                                                                         "`thermodrift export` wrote")
    if not zipfile.is_zipfile(path):
        raise PackageError("not an npz archive", file=str(path), hint="copy the whole folder that "
                                                                     "`thermodrift export` wrote")
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
    except Exception as exc:  # numpy raises ValueError, OSError, zipfile.BadZipFile, EOFError, KeyError, ...
        raise PackageError(f"unreadable ({type(exc).__name__}: {' '.join(str(exc).split())[:120]})",
                           file=str(path), hint="a package holds numeric arrays only; export the run again") from None
    for key, value in arrays.items():
        if value.dtype.kind not in "biuf":  # booleans, integers, floats: no text, complex or object arrays
            raise PackageError(f"array {key!r} holds {value.dtype} values, not numbers", file=str(path),
                               hint="a package holds numeric arrays only; export the run again")
    return arrays


def _tensors(path: Path) -> dict[str, Any]:
    """The tensors of ``weights.pt``, read with ``torch.load(weights_only=True)`` (no code runs)."""
    if not path.is_file():
        raise PackageError(f"no {WEIGHTS}", file=str(path.parent), hint="copy the whole folder that "
                                                                          "`thermodrift export` wrote")
    import torch

    try:
        tensors = torch.load(path, weights_only=True)
    except Exception as exc:  # torch raises RuntimeError, UnpicklingError, EOFError, ...
        raise PackageError(f"unreadable ({type(exc).__name__})", file=str(path),
                           hint="export the run again") from None
    if not isinstance(tensors, dict) or not all(isinstance(v, torch.Tensor) for v in tensors.values()):
        raise PackageError("not a mapping of tensors", file=str(path), hint="export the run again")
    return tensors


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
        raise PackageError(f"the training limits name no range for inputs {missing}", hint="refit the run")
    return {"model": model_state, "limits": limits, "safety": limits_mod.safety_defaults(limits),
            "sampling_interval_s": limits["sampling_interval_s"], "fallbacks": fallbacks or {},
            "axes": axes or {}, "probe": {"noise_um": probe.PROBE_NOISE_UM,
                                          "drift_um_per_sqrt_h": probe.BIAS_DRIFT_UM_PER_SQRT_H,
                                          "initial_um": probe.INITIAL_UM},
            "versions": versions or {}, "source": source or {}}
