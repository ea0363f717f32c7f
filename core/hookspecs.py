"""The plugin surface of thermodrift: one hook per component kind, each receiving ``registry``, the registry's
doors bound to the calling plugin (:class:`~thermodrift.core.registry.Registrar`: ``add``, ``add_searchpath``,
``add_hydra_plugin``), so every component records the distribution that registered it.

A plugin is a module named in the ``thermodrift`` entry-point group that implements any of these hooks::

    from thermodrift.core.hookspecs import hookimpl

    @hookimpl
    def thermodrift_register_models(registry):
        registry.add("model", "my_model", MyModel)

The compensator's modules (CNC formats, runtimes) write the same functions without ``hookimpl``: they import
nothing of core (see :mod:`thermodrift.compensator.discovery`), and the registry takes an unmarked function whose
name is one of these hooks.
"""

import pluggy

PROJECT = "thermodrift"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def thermodrift_register_selectors(registry):
    """Register sensitive-point selectors with ``registry.add("selector", name, cls)``."""


@hookspec
def thermodrift_register_models(registry):
    """Register thermal-error models (temperatures in °C -> displacement in µm) with ``registry.add("model", ...)``."""


@hookspec
def thermodrift_register_optimizers(registry):
    """Register Optuna sampler factories with ``registry.add("optimizer", name, factory)``; factories take ``seed``."""


@hookspec
def thermodrift_register_datasets(registry):
    """Register recording factories with ``registry.add("dataset", name, factory)``; factories return a Recording."""


@hookspec
def thermodrift_register_mechanisms(registry):
    """Register physics mechanisms (changes to a thermal network) with ``registry.add("mechanism", ...)``."""


@hookspec
def thermodrift_register_cnc_formats(registry):
    """Register controller formats (``thermodrift.compensator.cnc.Format`` classes): ``registry.add("cnc", ...)``."""


@hookspec
def thermodrift_register_runtimes(registry):
    """Register compensator runtimes (``cls(state)`` with ``inputs``, ``targets``, ``streamer()``): ``"runtime"``."""


@hookspec
def thermodrift_hydra_searchpaths(registry):
    """Add Hydra config search paths (``registry.add_searchpath("pkg://my_plugin.conf")``) for the plugin's YAML."""


@hookspec
def thermodrift_hydra_plugins(registry):
    """Add functions that register Hydra plugins (``registry.add_hydra_plugin(register)``); ``thermodrift run``
    calls each before Hydra starts (thermodrift's own Optuna sweeper comes in this way)."""
