"""Helpers shared by test modules (imported as ``support``: pytest puts this folder on the path)."""

import importlib.util
from pathlib import Path
from types import ModuleType
from typing import Callable


def load_file(path: Path, name: str | None = None,
              register: Callable[[str, ModuleType], None] | None = None) -> ModuleType:
    """The module in the file ``path`` (a script, a template, a benchmark), imported under ``name`` (default: the
    file's stem). ``register(name, module)`` is called before it runs, e.g. ``sys.modules.__setitem__`` when
    pickling or Hydra must import it again by name."""
    spec = importlib.util.spec_from_file_location(name or path.stem, path)
    module = importlib.util.module_from_spec(spec)
    if register is not None:
        register(spec.name, module)
    spec.loader.exec_module(module)
    return module
