"""Hydra config nodes built from the registry, so every registered component is selectable as ``group=name``.

At start-up :func:`store` puts one node per registered selector, model, optimizer and dataset into Hydra's
``ConfigStore`` (``name``, ``params`` = the constructor's defaults, models also ``search_space`` = the class's
own), unless a YAML file ``<group>/<name>.yaml`` exists on the search path: a shipped YAML overrides the node.
Hydra reads the store after every file source, but a YAML and a stored node of one name would be merged
(Hydra's deprecated "schema matching"), so a name with a YAML gets no node at all.

So the code is the one home of a component's defaults: a default changed in Python reaches ``thermodrift run``.
A YAML is a preset that differs from the node (S1's PSO settings as ``optimizer=pso_s1``) or configures a
factory whose parameters the node cannot see (``**params``); :func:`repeated_yamls` finds YAMLs that only
restate the node, and the test suite fails on any that thermodrift ships.
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import inspect
from pathlib import Path
from typing import Any

import yaml

from thermodrift.core.registry import CONFIG_GROUPS, Component, Registry

CONFIG_MODULE = "thermodrift.conf"
_PRIMARY = f"pkg://{CONFIG_MODULE}"


# Parameters a job passes itself, left out of the node so that they follow the run: the run's seed (selectors,
# models: registry.with_seed; optimizers: the sampler's seed) and the study's budget (optimizers).
_PASSED_BY_THE_JOB = {"selector": ("random_state", "seed"), "model": ("random_state", "seed"),
                      "optimizer": ("seed", "n_trials")}


def node(component: Component) -> dict[str, Any]:
    """The config a YAML would hold for ``component``: its name, constructor defaults, models' search space.

    A parameter without a default is ``???`` (Hydra's missing value: the command line must give it). Defaults
    that are not plain data (numbers, strings, lists, dicts, None) are left to the constructor, and so are the
    seed and budget a job passes itself.
    """
    params = {}
    try:
        signature = inspect.signature(component.factory)
    except (TypeError, ValueError):
        signature = None
    passed = _PASSED_BY_THE_JOB.get(component.kind, ())
    for pname, p in (signature.parameters.items() if signature else ()):
        if p.kind not in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) or pname in passed:
            continue
        if p.default is p.empty:
            params[pname] = "???"
        elif _plain(p.default):
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


def repeated_yamls(registry: Registry, searchpaths: list[str] | None = None) -> list[str]:
    """The YAML files (``<group>/<file>``) of thermodrift's configs and ``searchpaths`` that only restate the node
    of the component they name: every value they give equals the node's (``params`` compared key by key, so a
    subset of the defaults counts; ``search_space`` as a whole)."""
    out = []
    for kind, group in CONFIG_GROUPS.items():
        for option, path in sorted(yaml_files(list(searchpaths or []), group).items()):
            data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
            name = data.get("name", option)
            if name in registry.names(kind) and _repeats(data, node(registry.get(kind, name))):
                out.append(f"{group}/{option}.yaml")
    return out


def _repeats(given: Any, generated: Any, key: str = "") -> bool:
    if isinstance(given, dict) and isinstance(generated, dict) and key != "search_space":
        return all(k in generated and _repeats(v, generated[k], k) for k, v in given.items())
    return given == generated


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
