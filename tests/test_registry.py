"""The plugin registry: loading entry points, broken and conflicting distributions, names and create.

Fake distributions are real ``*.dist-info`` folders read with ``importlib.metadata.PathDistribution``; their
modules live on ``sys.path`` only for the test, their metadata never, so the process-wide registry cannot see them.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import subprocess
import sys
import textwrap
import uuid
from pathlib import Path

import optuna
import pytest

from thermodrift.core import registry
from thermodrift.core.errors import PluginError

LINEAR_MODEL = """
    from thermodrift.core.components import ThermalModel
    from thermodrift.core.hookspecs import hookimpl

    class Linear(ThermalModel):
        def __init__(self, alpha=0.0):
            self.alpha = alpha

    def sampler(seed=None):
        import optuna
        return optuna.samplers.RandomSampler(seed=seed)

    def unseeded_sampler():
        import optuna
        return optuna.samplers.RandomSampler()

    @hookimpl
    def thermodrift_register_models(registry):
        registry.add("model", "{model}", Linear)

    @hookimpl
    def thermodrift_register_optimizers(registry):
        registry.add("optimizer", "{model}_random", sampler)
        registry.add("optimizer", "{model}_unseeded", unseeded_sampler)
"""


@pytest.fixture
def make_dist(tmp_path, monkeypatch):
    """``make_dist(dist_name, {entry_point: module_source})`` -> the distribution's entry points."""
    src = tmp_path / "src"
    src.mkdir()
    monkeypatch.syspath_prepend(str(src))
    created: list[str] = []

    def make(dist_name: str, plugins: dict[str, str]) -> list[importlib.metadata.EntryPoint]:
        lines = []
        for ep_name, source in plugins.items():
            module = f"plugin_{uuid.uuid4().hex[:10]}"
            (src / f"{module}.py").write_text(textwrap.dedent(source))
            lines.append(f"{ep_name} = {module}")
            created.append(module)
        info = tmp_path / "meta" / f"{dist_name.replace('-', '_')}-1.0.dist-info"
        info.mkdir(parents=True)
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist_name}\nVersion: 1.0\n")
        (info / "entry_points.txt").write_text("[thermodrift]\n" + "\n".join(lines) + "\n")
        return list(importlib.metadata.PathDistribution(info).entry_points)

    yield make
    for module in created:
        sys.modules.pop(module, None)


def test_a_broken_distribution_is_reported_by_name_and_the_rest_load(make_dist):
    broken = make_dist("broken-plugin", {"boom": "raise RuntimeError('missing native library libfoo.so')"})
    failing_hook = make_dist("hook-fails-plugin", {"hooks": """
        from thermodrift.core.hookspecs import hookimpl

        @hookimpl
        def thermodrift_register_models(registry):
            raise KeyError("no such config")
    """})
    fine = make_dist("fine-plugin", {"models": LINEAR_MODEL.format(model="fine_linear")})

    reg = registry.load(broken + failing_hook + fine)

    by_dist = {key.split(" (")[0]: error for key, error in reg.failures.items()}
    assert by_dist.keys() == {"broken-plugin", "hook-fails-plugin"}
    assert reg.failures["broken-plugin (boom)"] == "RuntimeError: missing native library libfoo.so"
    assert by_dist["hook-fails-plugin"] == "KeyError: 'no such config'"
    assert reg.names("model") == ["fine_linear"]
    assert reg.get("model", "fine_linear").origin == "fine-plugin"


def test_a_misspelled_hook_is_reported_by_name_and_the_rest_load(make_dist):
    typo = make_dist("typo-plugin", {"typo": """
        from thermodrift.core.hookspecs import hookimpl

        @hookimpl
        def thermodrift_register_model(registry):
            pass
    """})
    fine = make_dist("fine-plugin", {"models": LINEAR_MODEL.format(model="fine_linear")})

    reg = registry.load(typo + fine)

    assert "thermodrift_register_model" in reg.failures["typo-plugin (typo)"]
    assert reg.names("model") == ["fine_linear"]


def test_a_duplicate_name_raises_naming_both_origins(make_dist):
    first = make_dist("alpha-plugin", {"models": LINEAR_MODEL.format(model="twin")})
    second = make_dist("beta-plugin", {"models": LINEAR_MODEL.format(model="twin")})
    with pytest.raises(PluginError, match=r"duplicate model name 'twin'.*alpha-plugin.*beta-plugin"):
        registry.load(first + second)


def test_names_create_and_their_errors(make_dist):
    reg = registry.load(make_dist("demo-plugin", {"models": LINEAR_MODEL.format(model="lin")}))
    assert reg.names("model") == ["lin"]
    assert reg.names("optimizer") == ["lin_random", "lin_unseeded"]
    assert reg.names("selector") == []

    model = reg.create("model", "lin", alpha=0.5)
    assert type(model).__name__ == "Linear" and model.get_params() == {"alpha": 0.5}
    sampler = reg.create("optimizer", "lin_random", seed=0)
    assert isinstance(sampler, optuna.samplers.BaseSampler)

    with pytest.raises(PluginError, match=r"unknown model 'nope'; known: lin"):
        reg.create("model", "nope")
    with pytest.raises(PluginError, match=r"unknown component kind 'models'"):
        reg.names("models")
    with pytest.raises(PluginError, match=r"'lin_unseeded' factory does not accept a seed"):
        reg.create("optimizer", "lin_unseeded", seed=0)


def test_the_module_api_builds_builtin_and_third_party_components():
    assert {"mlr", "persistence", "ridge_demo"} <= set(registry.names("model"))
    assert {"random", "tpe", "cmaes", "gp"} <= set(registry.names("optimizer"))
    assert isinstance(registry.create("optimizer", "tpe", seed=0), optuna.samplers.TPESampler)
    assert registry.create("model", "ridge_demo", alpha=0.1).get_params() == {"alpha": 0.1}


def test_the_third_party_components_come_from_their_distribution():
    reg = registry.load()
    for kind, name, module in [("model", "ridge_demo", "thermodrift_example_plugin"),
                               ("selector", "variance_top_k", "thermodrift_example_plugin.selectors"),
                               ("optimizer", "sobol_demo", "thermodrift_example_plugin.samplers")]:
        component = reg.get(kind, name)
        assert (component.origin, component.module) == ("thermodrift-example-plugin", module)
    assert all(reg.get("model", n).origin == "thermodrift" for n in ("mlr", "persistence"))


def test_hooks_run_through_pluggy_in_its_order_and_wrappers_wrap_each_plugin(make_dist):
    order_hook = """
        from thermodrift.core.hookspecs import hookimpl

        @hookimpl({spec})
        def thermodrift_register_models(registry):
            registry.add("selector", "{name}", lambda: None)
            registry.add("model", "{name}", lambda: None)
    """
    plain = make_dist("plain-plugin", {"m": order_hook.format(spec="", name="plain")})
    last = make_dist("last-plugin", {"m": order_hook.format(spec="trylast=True", name="last")})
    first = make_dist("first-plugin", {"m": order_hook.format(spec="tryfirst=True", name="first")})
    wrapper = make_dist("wrapper-plugin", {"w": """
        from thermodrift.core.hookspecs import hookimpl

        @hookimpl(wrapper=True)
        def thermodrift_register_models(registry):
            before = {k: set(v) for k, v in registry.components.items()}
            result = yield
            added = sorted(n for n in registry.components["model"] if n not in before["model"])
            registry.add("mechanism", "wrapped_" + "_".join(added), lambda: None)
            return result
    """})

    reg = registry.load(last + plain + first + wrapper)

    assert list(reg.components["model"]) == ["first", "plain", "last"]  # tryfirst, plain, trylast
    assert reg.names("mechanism") == ["wrapped_first", "wrapped_last", "wrapped_plain"]  # one call per plugin
    assert reg.get("mechanism", "wrapped_plain").origin == "plain-plugin"  # the wrapped plugin's origin
    assert {reg.get("model", n).origin for n in ("first", "plain", "last")} == {
        "first-plugin", "plain-plugin", "last-plugin"}


def test_a_plugin_that_fails_halfway_keeps_none_of_its_components(make_dist):
    half = make_dist("half-plugin", {"h": """
        from thermodrift.core.hookspecs import hookimpl

        @hookimpl
        def thermodrift_register_models(registry):
            registry.add("model", "half_done", lambda: None)
            raise RuntimeError("config file missing")
    """})
    reg = registry.load(half + make_dist("fine-plugin", {"models": LINEAR_MODEL.format(model="fine_linear")}))
    assert reg.names("model") == ["fine_linear"]
    assert reg.failures == {next(iter(reg.failures)): "RuntimeError: config file missing"}
    assert next(iter(reg.failures)).startswith("half-plugin (")


def test_the_hydra_sweeper_comes_through_the_entry_point_door():
    from hydra_plugins.thermodrift_sweeper import register

    assert registry.load().hydra_plugins == [register]
    source = (Path(registry.__file__).parent / "cli" / "run.py").read_text()
    assert "thermodrift_sweeper" not in source  # run.py knows no concrete Hydra plugin


def test_physics_is_pure_computation():
    """The mismatch map imports neither the tracking module nor MLflow: logging belongs to the verb."""
    code = ("import sys; import thermodrift.core.physics.mismatch; "
            "print(' '.join(m for m in ('thermodrift.core.tracking', 'mlflow') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert not out, f"importing the mismatch map imported {out}"


def test_loading_every_plugin_imports_neither_torch_nor_scipy_signal():
    """Listing the plugins must not pay for the imports that only training and simulation need (torch and
    scipy.signal, seconds together); the built-in bp, lptn, physics datasets and mechanisms all load here."""
    code = ("import sys; from thermodrift.core import registry; reg = registry.default(); "
            "assert 'bp' in reg.names('model') and 'lptn' in reg.names('model'), reg.names('model'); "
            "assert not reg.failures, reg.failures; "
            "print(' '.join(m for m in ('torch', 'scipy.signal') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert not out, f"loading the registry imported {out}"


_LISTING = ("import json, sys; from thermodrift.core import registry; ls = registry.listing(); "
            "print(json.dumps([ls.components, 'sklearn' in sys.modules]))")


def _listing_in_a_new_process(cache_dir: Path) -> tuple[dict, bool]:
    env = {**os.environ, "THERMODRIFT_CACHE_DIR": str(cache_dir)}
    env.pop("THERMODRIFT_NO_CACHE", None)
    out = subprocess.run([sys.executable, "-c", _LISTING], capture_output=True, text=True, env=env, check=True)
    components, imported_sklearn = json.loads(out.stdout.strip().splitlines()[-1])
    return components, imported_sklearn


def test_the_listing_is_saved_by_a_full_load_and_read_back_without_importing_the_plugins(tmp_path):
    loaded = {k: registry.default().names(k) for k in registry.KINDS}
    first, imported_first = _listing_in_a_new_process(tmp_path)
    second, imported_second = _listing_in_a_new_process(tmp_path)
    assert first == second == loaded
    assert imported_first and not imported_second  # the second one read the saved listing


def test_the_saved_listing_is_not_used_once_a_plugin_file_changed(tmp_path):
    _listing_in_a_new_process(tmp_path)
    (saved,) = tmp_path.glob("components-*.json")
    data = json.loads(saved.read_text())
    plugin_file = tmp_path / "plugin_module.py"
    plugin_file.write_text("x = 1\n")
    data["files"][str(plugin_file)] = registry._stat(str(plugin_file))
    data["components"]["model"].append("removed_since")
    saved.write_text(json.dumps(data))
    components, imported = _listing_in_a_new_process(tmp_path)
    assert "removed_since" in components["model"] and not imported  # unchanged files: the listing is trusted
    plugin_file.write_text("x = 22\n")  # a plugin's source changed: the listing is rebuilt by a full load
    components, imported = _listing_in_a_new_process(tmp_path)
    assert imported and "removed_since" not in components["model"]
