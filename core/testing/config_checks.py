"""The Hydra config of a registered component composes and builds the component.

Composition is what ``thermodrift run`` does: the primary config ``pkg://thermodrift.conf/config.yaml`` with
``hydra.searchpath`` set to the search paths that plugins contribute, the registry's config nodes
(:mod:`thermodrift.core.configs`: every component without a YAML), and ``<group>=<name>`` as override.
"""

from __future__ import annotations

from typing import Any

import optuna
from hydra import compose, initialize_config_module
from hydra.core.global_hydra import GlobalHydra
from omegaconf import DictConfig, OmegaConf

from thermodrift.core import configs
from thermodrift.core.configs import CONFIG_MODULE
from thermodrift.core.errors import InputError
from thermodrift.core.registry import CONFIG_GROUPS, Registry
from thermodrift.core.search_space import distributions


def compose_config(overrides: list[str], searchpaths: list[str], registry: Registry | None = None) -> DictConfig:
    """The composed run config for ``overrides``, with plugin config ``searchpaths`` (``pkg://...``) and the
    config nodes of ``registry``'s components (stored in Hydra's ConfigStore first)."""
    if registry is not None:
        configs.store(registry)
    outer = GlobalHydra.instance().hydra  # a caller inside a Hydra app keeps its Hydra
    GlobalHydra.instance().clear()
    try:
        with initialize_config_module(CONFIG_MODULE, version_base="1.3"):
            return compose("config", overrides=[*overrides, f"hydra.searchpath=[{','.join(searchpaths)}]"])
    finally:
        if outer is not None:
            GlobalHydra.instance().clear()
            GlobalHydra.instance().initialize(outer)


def check_hydra_config(kind: str, name: str, registry: Registry) -> None:
    """``<group>=<name>`` composes (from a YAML or the registry's node), names the component, and its ``params``
    build it (models: valid search_space)."""
    group = CONFIG_GROUPS[kind]
    try:
        cfg = compose_config([f"{group}={name}"], registry.searchpaths, registry)
        node: dict[str, Any] = OmegaConf.to_container(cfg[group], resolve=True)
    except Exception as exc:  # Hydra's errors are long; the first line says what is missing
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise AssertionError(f"config {group}={name} does not compose: {first}") from None
    assert node.get("name") == name, f"{group}/{name}.yaml must hold 'name: {name}', found name: {node.get('name')!r}"
    params = node.get("params") or {}
    assert isinstance(params, dict), f"{group}/{name}.yaml: params must be a mapping of constructor arguments"
    if kind == "dataset":  # building a dataset may read a large file; its factory is checked separately
        return
    if kind == "optimizer":
        built = registry.create(kind, name, seed=0, **params)
        assert isinstance(built, optuna.samplers.BaseSampler), f"{group}/{name}.yaml params do not build a sampler"
        return
    built = registry.create(kind, name, **params)
    space = node.get("search_space") or {}
    try:
        distributions(space)
    except InputError as exc:
        raise AssertionError(f"{group}/{name}.yaml: {exc}") from None
    unknown = sorted(set(space) - set(built.get_params(deep=True)))
    assert not unknown, f"{group}/{name}.yaml: search_space names {unknown}, which are not constructor parameters"
