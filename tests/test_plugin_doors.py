"""Plugins reach core and each other through public doors: the registry's doors handed to each plugin bound to
its origin, samplers and trainer parts taken from their public homes (private names: tests/test_import_rules.py)."""

import ast
import importlib.metadata
import sys
import textwrap
from pathlib import Path

from thermodrift.core import registry

PLUGINS = Path(registry.__file__).parents[1] / "plugins"


def _imports(path: Path):
    """(module, name) for every ``from module import name`` and (module, None) for every ``import module``."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module:
            yield from ((node.module, alias.name) for alias in node.names)
        elif isinstance(node, ast.Import):
            yield from ((alias.name, None) for alias in node.names)


def test_models_and_samplers_stay_independent():
    """A model that needs a sampler asks the registry for it (pso_bpnn, like the hdbscan_pso selector)."""
    for folder, other in (("models", "optimizers"), ("optimizers", "models"), ("selectors", "optimizers")):
        for path in sorted((PLUGINS / folder).glob("*.py")):
            assert not [m for m, _ in _imports(path) if m.startswith(f"thermodrift.plugins.{other}")], path.name


def test_pso_bpnn_uses_the_trainers_own_validation_split(monkeypatch):
    """The swarm fits on exactly the rows the trainer trains on (training.training_rows), not a copy of the rule."""
    from thermodrift.core import training
    from thermodrift.plugins.models import pso_bpnn
    from thermodrift.testing import tiny_frames

    asked = []
    real = training.training_rows

    def spy(n, config):
        asked.append(n)
        return real(n, config)

    monkeypatch.setattr(training, "training_rows", spy)
    monkeypatch.setattr(pso_bpnn, "training_rows", spy, raising=False)
    X, y = tiny_frames()
    model = registry.create("model", "pso_bpnn", hidden_units=3, swarm_size=3, pso_iterations=2,
                            trainer={"epochs": 2, "t0": 1})
    model.fit(X, y)
    assert asked == [len(X), len(X)]  # the swarm's split, then the trainer's: one rule


def test_each_hook_gets_a_registrar_bound_to_its_plugin(tmp_path, monkeypatch):
    src = tmp_path / "src"
    src.mkdir()
    monkeypatch.syspath_prepend(str(src))
    (src / "doors_probe_plugin.py").write_text(textwrap.dedent("""
        from thermodrift.core.hookspecs import hookimpl

        SEEN = []

        @hookimpl
        def thermodrift_register_models(registry):
            SEEN.append((type(registry).__name__, registry.origin, registry.module))
            registry.add("model", "doors_probe", lambda: None)
    """))
    info = tmp_path / "doors_probe-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: doors-probe\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[thermodrift]\nprobe = doors_probe_plugin\n")
    try:
        reg = registry.load(list(importlib.metadata.PathDistribution(info).entry_points))
        assert sys.modules["doors_probe_plugin"].SEEN == [("Registrar", "doors-probe", "doors_probe_plugin")]
    finally:
        sys.modules.pop("doors_probe_plugin", None)
    component = reg.get("model", "doors_probe")
    assert (component.origin, component.module) == ("doors-probe", "doors_probe_plugin")
    assert not any(name.startswith("_") for name in vars(reg))  # no per-call private state on the registry


def test_cnc_formats_and_runtimes_are_doors_the_compensator_reads_without_core():
    """The registry and the compensator's own reader (standard library only) see the same formats and runtimes,
    built-in and third-party, through the same entry points."""
    from thermodrift.compensator import discovery

    reg = registry.default()
    for kind in ("cnc", "runtime"):
        assert sorted(discovery.components(kind)) == reg.names(kind)
    assert all(discovery.components("cnc")[n] is reg.get("cnc", n).factory for n in reg.names("cnc"))
    assert {"csv", "siemens", "fanuc", "beckhoff"} <= set(reg.names("cnc"))
    assert {"linear", "transfer_function", "lptn", "sequence", "pipeline", "ensemble"} <= set(reg.names("runtime"))
    assert reg.get("cnc", "siemens").module == "thermodrift.compensator.cnc.siemens"


def test_an_unmarked_hook_function_registers(tmp_path, monkeypatch):
    """A module of the compensator writes its hook without ``hookimpl`` (it imports neither core nor pluggy)."""
    src = tmp_path / "src"
    src.mkdir()
    monkeypatch.syspath_prepend(str(src))
    (src / "plain_door_plugin.py").write_text(textwrap.dedent("""
        class Words:
            pass

        def thermodrift_register_cnc_formats(registry):
            registry.add("cnc", "plain_words", Words)
    """))
    info = tmp_path / "plain_door-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: plain-door\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[thermodrift]\nwords = plain_door_plugin\n")
    try:
        reg = registry.load(list(importlib.metadata.PathDistribution(info).entry_points))
    finally:
        sys.modules.pop("plain_door_plugin", None)
    assert reg.names("cnc") == ["plain_words"] and reg.get("cnc", "plain_words").origin == "plain-door"
