"""Hydra config nodes built from the registry, so every registered component is selectable as ``group=name``.

At start-up :func:`store` puts one node per registered selector, model, optimizer and dataset into Hydra's
``ConfigStore`` (``name``, ``params`` = the constructor's defaults, models also ``search_space`` = the class's
own), unless a YAML file ``<group>/<name>.yaml`` exists on the search path: a shipped YAML overrides the node.
Hydra reads the store after every file source, but a YAML and a stored node of one name would be merged
(Hydra's deprecated "schema matching"), so a name with a YAML gets no node at all.
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import inspect
from pathlib import Path
from typing import Any

from thermodrift.core.registry import CONFIG_GROUPS, Component, Registry

CONFIG_MODULE = "thermodrift.conf"
_PRIMARY = f"pkg://{CONFIG_MODULE}"


def node(component: Component) -> dict[str, Any]:
    """The config a YAML would hold for ``component``: its name, constructor defaults, models' search space.

    Defaults that are not plain data (numbers, strings, lists, dicts, None) are left to the constructor.
    """
    params = {}
    try:
        signature = inspect.signature(component.factory)
    except (TypeError, ValueError):
        signature = None
    for pname, p in (signature.parameters.items() if signature else ()):
        if (p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.default is not p.empty
                and not (component.kind == "optimizer" and pname in ("seed", "n_trials")) and _plain(p.default)):
            params[pname] = list(p.default) if isinstance(p.default, tuple) else p.default
    trainer_defaults = getattr(component.factory, "trainer_defaults", None)  # torch models' TrainerSettings
    if "trainer" in params and dataclasses.is_dataclass(trainer_defaults):
        params["trainer"] = dataclasses.asdict(trainer_defaults)  # so `model.params.trainer.epochs=50` works
    cfg: dict[str, Any] = {"name": component.name, "params": params}
    if component.kind == "model":
        space = getattr(component.factory, "search_space", None)
        cfg["search_space"] = space() if callable(space) else {}
    return cfg


def _plain(value: Any) -> bool:
    if value is None or isinstance(value, (bool, int, float, str)):
        return True
    if isinstance(value, (list, tuple)):
        return all(_plain(v) for v in value)
    if isinstance(value, dict):
        return all(isinstance(k, str) and _plain(v) for k, v in value.items())
    return False


def yaml_files(searchpaths: list[str], group: str) -> dict[str, Any]:
    """Option name -> YAML file (a path or package resource) of ``group`` in thermodrift's configs and in
    ``searchpaths`` (``pkg://package.sub`` or ``file://dir`` / a directory); the first path wins, as in Hydra."""
    found: dict[str, Any] = {}
    for path in (_PRIMARY, *searchpaths):
        if path.startswith("pkg://"):
            try:
                folder = importlib.resources.files(path[len("pkg://"):]).joinpath(group)
                files = list(folder.iterdir()) if folder.is_dir() else []
            except (ModuleNotFoundError, TypeError):  # a search path of an uninstalled package finds nothing
                continue
        else:
            folder = Path(path.removeprefix("file://")) / group
            files = list(folder.iterdir()) if folder.is_dir() else []
        for f in files:
            if f.name.endswith(".yaml"):
                found.setdefault(f.name[: -len(".yaml")], f)
    return found


def store(registry: Registry) -> None:
    """Put a config node for every registered component without a YAML into Hydra's ConfigStore (a later call
    replaces the nodes of the same names)."""
    from hydra.core.config_store import ConfigStore

    cs = ConfigStore.instance()
    for kind, group in CONFIG_GROUPS.items():
        shipped = yaml_files(registry.searchpaths, group)
        for name in registry.names(kind):
            if name not in shipped:
                component = registry.get(kind, name)
                cs.store(group=group, name=name, node=node(component), provider=component.origin)
