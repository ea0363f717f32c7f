"""Discover plugins through the ``thermodrift`` entry-point group and build components by name.

Public API (stable)::

    from thermodrift.core import registry
    registry.names("model")                      # ['bp', 'mlr', 'persistence', ...]
    registry.create("optimizer", "tpe", seed=0)  # an optuna.samplers.BaseSampler

Built-in plugins are entry points of the ``thermodrift`` distribution, so they load through the same door as
third-party ones. A distribution whose plugin fails to import or to register is reported by name
(``registry.default().failures``) and the others still load; two components of one kind with the same name
are an error that names both origins.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import inspect
import json
import os
import sys
from pathlib import Path
from dataclasses import dataclass, field
from typing import Any, Callable

import pluggy

from thermodrift.core import hookspecs
from thermodrift.core.errors import DuplicateComponentError, PluginError

KINDS = ("selector", "model", "optimizer", "dataset", "mechanism", "cnc", "runtime")
_HOOKS = {
    "selector": "thermodrift_register_selectors",
    "model": "thermodrift_register_models",
    "optimizer": "thermodrift_register_optimizers",
    "dataset": "thermodrift_register_datasets",
    "mechanism": "thermodrift_register_mechanisms",
    "cnc": "thermodrift_register_cnc_formats",
    "runtime": "thermodrift_register_runtimes",
}
HOOKS = (*_HOOKS.values(), "thermodrift_hydra_searchpaths", "thermodrift_hydra_plugins")
# What a plugin may raise while loading without stopping the others: anything but KeyboardInterrupt.
_PLUGIN_FAULTS = (Exception, SystemExit, GeneratorExit)
# The Hydra config group that configures each kind (conf/<group>/<name>.yaml).
CONFIG_GROUPS = {"selector": "selector", "model": "model", "optimizer": "optimizer", "dataset": "dataset"}


@dataclass(frozen=True)
class Component:
    """A registered component: its kind, name, factory (class or callable) and origin distribution."""

    kind: str
    name: str
    factory: Callable[..., Any]
    origin: str
    module: str


@dataclass
class Registry:
    """Components by kind and name, filled by the plugins' hooks.

    Each hook gets a :class:`Registrar` bound to its plugin's origin (``registry.add(kind, name, factory)`` in the
    hook); :meth:`add` called on the registry itself records the given ``origin`` and ``module``.
    """

    components: dict[str, dict[str, Component]] = field(default_factory=lambda: {k: {} for k in KINDS})
    searchpaths: list[str] = field(default_factory=list)
    hydra_plugins: list[Callable[[], None]] = field(default_factory=list)
    failures: dict[str, str] = field(default_factory=dict)  # "distribution (entry point)" -> error

    def add(self, kind: str, name: str, factory: Callable[..., Any], *, origin: str = "<unknown>",
            module: str = "<unknown>") -> None:
        """Register ``factory`` (a class or callable) as component ``name`` of ``kind``, from plugin module
        ``module`` of distribution ``origin``."""
        if kind not in KINDS:
            raise PluginError(f"{origin}: unknown component kind {kind!r}; use one of {', '.join(KINDS)}")
        if not callable(factory):
            raise PluginError(f"{origin}: {kind} {name!r} is not callable")
        known = self.components[kind].get(name)
        if known is not None:
            raise DuplicateComponentError(
                f"duplicate {kind} name {name!r}: registered by {known.origin} ({known.module}) "
                f"and by {origin} ({module}); rename one of them")
        self.components[kind][name] = Component(kind, name, factory, origin, module)

    def params(self, kind: str, name: str) -> list[str] | None:
        """The keyword parameters of component ``name`` (see :func:`parameters`); None when unknown or open."""
        found = self.components.get(kind, {}).get(name)
        return parameters(found.factory) if found else None

    def registrar(self, origin: str, module: str = "<unknown>") -> "Registrar":
        """What a plugin's hook receives: this registry's doors, bound to the plugin's origin."""
        return Registrar(self, origin, module)

    def add_searchpath(self, path: str) -> None:
        """Add a Hydra config search path such as ``pkg://my_plugin.conf``."""
        if path not in self.searchpaths:
            self.searchpaths.append(path)

    def add_hydra_plugin(self, register: Callable[[], None]) -> None:
        """Add a function that registers Hydra plugins (a sweeper, a launcher) with Hydra; ``thermodrift run``
        calls it before Hydra starts. Hydra's own scan of ``hydra_plugins`` misses plugins served by an
        editable install's import hook, so this door works in every install mode."""
        if register not in self.hydra_plugins:
            self.hydra_plugins.append(register)

    def drop(self, origin: str, module: str) -> None:
        """Remove every component that the plugin module ``module`` of distribution ``origin`` registered."""
        for comps in self.components.values():
            for name in [n for n, c in comps.items() if (c.origin, c.module) == (origin, module)]:
                del comps[name]

    def names(self, kind: str) -> list[str]:
        """Sorted component names of ``kind``."""
        return sorted(self._of(kind))

    def get(self, kind: str, name: str) -> Component:
        """The registered component, or a one-line error listing the known names."""
        comps = self._of(kind)
        if name not in comps:
            raise PluginError(f"unknown {kind} {name!r}; known: {', '.join(sorted(comps)) or 'none'}")
        return comps[name]

    def create(self, kind: str, name: str, **params: Any) -> Any:
        """Build component ``name`` of ``kind`` with ``params`` (for optimizers pass ``seed``)."""
        factory = self.get(kind, name).factory
        if kind == "optimizer" and "seed" in params and not accepts(factory, "seed"):
            raise PluginError(f"optimizer {name!r} factory does not accept a seed")
        return build(factory, params)

    def _of(self, kind: str) -> dict[str, Component]:
        if kind not in KINDS:
            raise PluginError(f"unknown component kind {kind!r}; use one of {', '.join(KINDS)}")
        return self.components[kind]


@dataclass(frozen=True)
class Registrar:
    """The registry as one plugin sees it: every component it adds records the plugin's distribution
    (``origin``) and module, so a duplicate name or a failed plugin is reported by name."""

    registry: Registry
    origin: str
    module: str

    def add(self, kind: str, name: str, factory: Callable[..., Any]) -> None:
        """Register ``factory`` (a class or callable) as component ``name`` of ``kind``."""
        self.registry.add(kind, name, factory, origin=self.origin, module=self.module)

    def add_searchpath(self, path: str) -> None:
        """Add a Hydra config search path such as ``pkg://my_plugin.conf``."""
        self.registry.add_searchpath(path)

    def add_hydra_plugin(self, register: Callable[[], None]) -> None:
        """Add a function that registers Hydra plugins (see :meth:`Registry.add_hydra_plugin`)."""
        self.registry.add_hydra_plugin(register)

    @property
    def components(self) -> dict[str, dict[str, Component]]:
        """What is registered so far, by kind and name (a hook wrapper reads what the wrapped plugin added)."""
        return self.registry.components

    def names(self, kind: str) -> list[str]:
        """Sorted names of the components of ``kind`` registered so far."""
        return self.registry.names(kind)


def accepts(factory: Callable[..., Any], param: str) -> bool:
    """Whether ``factory`` takes keyword ``param`` (by name or through ``**kwargs``)."""
    try:
        sig = inspect.signature(factory)
    except (TypeError, ValueError):
        return True
    return param in sig.parameters or any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values())


def parameters(factory: Callable[..., Any]) -> list[str] | None:
    """The keyword parameters of ``factory``, sorted; None when it takes ``**kwargs`` or has no signature."""
    try:
        signature = inspect.signature(factory)
    except (TypeError, ValueError):
        return None
    if any(p.kind is p.VAR_KEYWORD for p in signature.parameters.values()):
        return None
    return sorted(n for n, p in signature.parameters.items() if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY))


def with_seed(factory: Callable[..., Any], params: dict[str, Any], seed: int) -> dict[str, Any]:
    """``params`` plus ``seed`` under the name the component uses for it (``random_state`` or ``seed``), if it
    takes one and ``params`` does not set it."""
    out = dict(params)
    for key in ("random_state", "seed"):
        if accepts(factory, key):
            out.setdefault(key, seed)
            break
    return out


def build(factory: Callable[..., Any], params: dict[str, Any]) -> Any:
    """``factory(**params)``, where scikit-learn's nested names (``trainer__lr_max``) are set afterwards
    through the built object's ``set_params``, so a search space can tune a component's nested settings."""
    nested = {k: v for k, v in params.items() if "__" in k}
    built = factory(**{k: v for k, v in params.items() if k not in nested})
    return built.set_params(**nested) if nested else built


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    """The ``thermodrift`` entry points of every installed distribution, in load order."""
    return sorted(importlib.metadata.entry_points(group=hookspecs.PROJECT),
                  key=lambda ep: (ep.dist.name if ep.dist else "", ep.name))


def load(entry_points: list[importlib.metadata.EntryPoint] | None = None) -> Registry:
    """Load every plugin of the ``thermodrift`` entry-point group into a fresh :class:`Registry`.

    Every hook is called through pluggy, once per implementing plugin (a subset hook caller holding that
    plugin and every hook wrapper), in pluggy's order (``tryfirst``/``trylast``, then the last registered
    first; plugins are registered in reverse, so those of equal rank are called in the order of
    ``entry_points``). So each component records the distribution it came from, wrappers wrap each plugin's
    call, and a plugin whose import or hook fails is reported by name, keeps none of its components, and
    the others still load.
    """
    if entry_points is None:
        entry_points = _entry_points()
    manager = _Manager(hookspecs.PROJECT)
    manager.add_hookspecs(hookspecs)
    registry = Registry()
    origins: dict[str, tuple[str, str, str]] = {}  # plugin name -> (distribution, failure key, module)
    for ep in reversed(entry_points):  # pluggy calls the last registered first: calls follow the given order
        origin = ep.dist.name if ep.dist else "<unknown>"
        key, name = f"{origin} ({ep.name})", f"{origin}:{ep.name}"
        try:
            manager.register(ep.load(), name=name)
            manager.check_pending()  # a misspelled hook fails this plugin only
        except _PLUGIN_FAULTS as exc:  # a broken third-party distribution must not stop the rest
            if manager.get_plugin(name) is not None:
                manager.unregister(name=name)
            registry.failures[key] = _one_line(exc)
            continue
        origins[name] = (origin, key, ep.value)
    for hook_name in HOOKS:
        impls = getattr(manager.hook, hook_name).get_hookimpls()
        wrappers = {i.plugin_name for i in impls if i.hookwrapper or i.wrapper}
        plain = [i for i in reversed(impls) if i.plugin_name not in wrappers]  # pluggy calls the list reversed
        for impl in plain:
            origin, key, module_name = origins[impl.plugin_name]
            if key in registry.failures:
                continue
            others = [i.plugin for i in plain if i is not impl]
            try:
                manager.subset_hook_caller(hook_name, remove_plugins=others)(
                    registry=registry.registrar(origin, module_name))
            except DuplicateComponentError:
                raise
            except _PLUGIN_FAULTS as exc:  # same rule as for import failures; what it added is dropped
                registry.failures[key] = _one_line(exc)
                registry.drop(origin, module_name)
    return registry


class _Manager(pluggy.PluginManager):
    """pluggy's manager that also takes an unmarked function named like one of thermodrift's hooks (pytest does
    the same for ``pytest_*``): the compensator's modules register formats and runtimes that way, importing
    neither core nor pluggy."""

    def parse_hookimpl_opts(self, plugin, name):
        opts = super().parse_hookimpl_opts(plugin, name)
        if opts is None and name in HOOKS and inspect.isfunction(getattr(plugin, name, None)):
            return {}  # the defaults (not tryfirst, not a wrapper)
        return opts


def _one_line(exc: BaseException) -> str:
    return " ".join(f"{type(exc).__name__}: {exc}".split())


_DEFAULT: Registry | None = None


def default() -> Registry:
    """The process-wide registry, loaded on first use; its listing is saved for :func:`listing`."""
    global _DEFAULT
    if _DEFAULT is None:
        entry_points = _entry_points()
        before = set(sys.modules)
        _DEFAULT = load(entry_points)
        _save_listing(_DEFAULT, entry_points, set(sys.modules) - before)
    return _DEFAULT


@dataclass(frozen=True)
class Listing:
    """What is installed, by name only: component names per kind, Hydra search paths, failed plugins."""

    components: dict[str, list[str]]
    searchpaths: list[str]
    failures: dict[str, str]
    parameters: dict[str, dict[str, list[str] | None]] = field(default_factory=dict)  # kind -> name -> keywords

    def names(self, kind: str) -> list[str]:
        """Sorted component names of ``kind``."""
        return list(self.components.get(kind, []))

    def params(self, kind: str, name: str) -> list[str] | None:
        """The keyword parameters of component ``name`` (see :func:`parameters`); None when unknown or open."""
        return self.parameters.get(kind, {}).get(name)


# Listing the components means importing every plugin, and plugins import scikit-learn, scipy and pandas
# (about 2 s on a 2-core machine). ``thermodrift run --help`` needs only the names, so the last full load's
# names are kept in a small JSON file, valid while the installed entry points and every file of the plugins'
# own packages that the load imported are unchanged (same size and modification time). Neither importlib nor
# pluggy keeps such a listing.
_CACHE_VERSION = 3


def _cache_file(entry_points: list[importlib.metadata.EntryPoint]) -> Path | None:
    root = os.environ.get("THERMODRIFT_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "thermodrift")
    if os.environ.get("THERMODRIFT_NO_CACHE"):
        return None
    key = json.dumps([_CACHE_VERSION, sys.prefix, sys.version, _described(entry_points)])
    return Path(root) / f"components-{hashlib.sha256(key.encode()).hexdigest()[:16]}.json"


def _described(entry_points: list[importlib.metadata.EntryPoint]) -> list[list[str]]:
    return [[ep.dist.name if ep.dist else "", ep.dist.version if ep.dist else "", ep.name, ep.value]
            for ep in entry_points]


def _stat(path: str) -> list[int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return [st.st_mtime_ns, st.st_size]


def _save_listing(reg: Registry, entry_points: list[importlib.metadata.EntryPoint], imported: set[str]) -> None:
    """Write the listing of a full load, with the stat of every imported file of the plugins' packages."""
    target = _cache_file(entry_points)
    if target is None:
        return
    tops = {ep.value.split(":")[0].split(".")[0] for ep in entry_points}
    files = {}
    for name in imported:
        path = getattr(sys.modules.get(name), "__file__", None)
        if name.split(".")[0] in tops and path:
            files[path] = _stat(path)
    data = {"entry_points": _described(entry_points), "files": files,
            "components": {k: reg.names(k) for k in KINDS}, "parameters": _parameters(reg),
            "searchpaths": reg.searchpaths, "failures": reg.failures}
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(data), encoding="utf-8")
        os.replace(tmp, target)  # atomic: a concurrent reader sees the old or the new file, never half of one
    except OSError:  # a read-only home only costs speed
        pass


def listing() -> Listing:
    """Component names, search paths and failures of the installed plugins, read from the saved listing when
    nothing installed changed since the last full load, else by loading the registry (which saves it)."""
    entry_points = _entry_points()
    target = _cache_file(entry_points)
    if _DEFAULT is None and target is not None:
        try:
            data = json.loads(target.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            data = None
        if (data and data.get("entry_points") == _described(entry_points)
                and all(_stat(path) == stat for path, stat in data["files"].items())):
            return Listing(data["components"], data["searchpaths"], data["failures"], data.get("parameters", {}))
    reg = default()
    return Listing({k: reg.names(k) for k in KINDS}, list(reg.searchpaths), dict(reg.failures), _parameters(reg))


def _parameters(reg: Registry) -> dict[str, dict[str, list[str] | None]]:
    return {k: {n: reg.params(k, n) for n in reg.names(k)} for k in KINDS}


def names(kind: str) -> list[str]:
    """Sorted names of the registered components of ``kind`` ("selector", "model", "optimizer", ...)."""
    return default().names(kind)


def create(kind: str, name: str, **params: Any) -> Any:
    """Build a registered component; ``create("optimizer", name, seed=0)`` returns an Optuna sampler."""
    return default().create(kind, name, **params)


def create_sampler(name: str, *, seed: int | None, n_trials: int, **params: Any) -> Any:
    """The registered optimizer ``name`` as an Optuna sampler; factories whose schedules need the budget
    (they take ``n_trials``) get the study's ``n_trials`` unless ``params`` set it."""
    if accepts(get("optimizer", name).factory, "n_trials"):
        params.setdefault("n_trials", n_trials)
    return create("optimizer", name, seed=seed, **params)


def get(kind: str, name: str) -> Component:
    """The registered :class:`Component` of ``kind`` named ``name``."""
    return default().get(kind, name)
