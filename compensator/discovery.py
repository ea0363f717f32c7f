"""The compensator's doors, read without ``thermodrift.core``: CNC formats and runtimes found through the
``thermodrift`` entry points, the same door as every other component.

A module adds a controller format or a runtime with a plain function (no marker needed, so a module of this
package imports neither core nor pluggy; a third-party module may use ``thermodrift.core.hookspecs.hookimpl``)::

    def thermodrift_register_cnc_formats(registry):
        registry.add("cnc", "my_controller", MyFormat)      # a cnc.Format subclass

    def thermodrift_register_runtimes(registry):
        registry.add("runtime", "my_family", MyRuntime)     # MyRuntime(state) -> .inputs, .targets, .streamer()

plus one line in the distribution's ``[project.entry-points.thermodrift]``. ``thermodrift.core.registry`` calls
the same functions through pluggy (for ``thermodrift plugins``, the conformance suite and the CLI's choices);
this reader serves a controller-side program that loads a package with numpy alone. It imports the
compensator's own modules and those of other distributions, never thermodrift's training plugins.
"""

from __future__ import annotations

import importlib.metadata
from functools import lru_cache
from typing import Any, Callable

HOOKS = {"cnc": "thermodrift_register_cnc_formats", "runtime": "thermodrift_register_runtimes"}
_OWN = "thermodrift.compensator."


class _Collector:
    """What a hook function receives here: ``add(kind, name, factory)``; other kinds are left to the registry."""

    def __init__(self, found: dict[str, dict[str, Callable[..., Any]]], origin: str):
        self.found, self.origin = found, origin

    def add(self, kind: str, name: str, factory: Callable[..., Any]) -> None:
        if kind in self.found:
            self.found[kind].setdefault(name, factory)  # the registry reports duplicates by name


@lru_cache(maxsize=2)
def _discover(others: bool) -> tuple[dict[str, dict[str, Callable[..., Any]]], dict[str, str]]:
    """What the compensator's own modules register and, with ``others``, the other distributions' modules too."""
    found: dict[str, dict[str, Callable[..., Any]]] = {kind: {} for kind in HOOKS}
    failures: dict[str, str] = {}
    eps = sorted(importlib.metadata.entry_points(group="thermodrift"),
                 key=lambda ep: (not ep.value.startswith(_OWN), ep.dist.name if ep.dist else "", ep.name))
    for ep in eps:
        dist = ep.dist.name if ep.dist else "<unknown>"
        if not ep.value.startswith(_OWN) and (dist == "thermodrift" or not others):
            continue  # thermodrift's training plugins register neither formats nor runtimes
        try:
            module = ep.load()
            for hook in HOOKS.values():
                if callable(getattr(module, hook, None)):
                    getattr(module, hook)(_Collector(found, dist))
        except Exception as exc:  # a broken third-party plugin must not stop a controller (the registry names it)
            failures[f"{dist} ({ep.name})"] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    return found, failures


def components(kind: str) -> dict[str, Callable[..., Any]]:
    """Name -> factory of every installed component of ``kind`` (``"cnc"`` or ``"runtime"``)."""
    return dict(_discover(True)[0][kind])


def find(kind: str, name: str) -> Callable[..., Any] | None:
    """The factory of component ``name`` of ``kind``; other distributions' plugins are imported only when the
    compensator's own modules do not have it (a package of a built-in family loads with numpy alone)."""
    own = _discover(False)[0][kind]
    return own[name] if name in own else _discover(True)[0][kind].get(name)


def failures() -> dict[str, str]:
    """Plugins that failed to load here: "distribution (entry point)" -> error."""
    return dict(_discover(True)[1])
