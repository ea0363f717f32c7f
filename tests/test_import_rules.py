"""Import rules and the shape of the code, over the whole package (core, plugins, compensator, the Hydra sweeper):
the layers of docs/architecture.md (the compensator lowest, importing nothing of core; the CLI on top, imported by
nothing), which third-party stacks each layer may import, data knows no experiment, physics imports neither tracking
nor the CLI, plugins use only public names of core and of each other, one home for the temperature roles, no module
over 600 lines (benchmarks included). Read from the source (every import, also those inside functions), so nothing
needs importing."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).parents[1]
MAX_LINES = 600


def _modules(folder: str) -> list[Path]:
    return sorted((REPO / folder).rglob("*.py"))


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """(module, imported names) of every import statement in ``path``, relative ones resolved."""
    package = ["thermodrift", *path.relative_to(REPO).with_suffix("").parts[:-1]]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            module = ".".join([*base, *([node.module] if node.module else [])])
            out.append((module, [a.name for a in node.names]))
    return out


def _offenders(folder: str, forbidden: tuple[str, ...]) -> list[str]:
    return [f"{p.relative_to(REPO)} imports {m}" for p in _modules(folder) for m, _ in _imports(p)
            if any(m == f or m.startswith(f + ".") for f in forbidden)]


def test_physics_imports_neither_tracking_nor_the_cli():
    assert _offenders("core/physics", ("thermodrift.core.tracking", "thermodrift.core.cli", "mlflow")) == []


def test_data_knows_no_experiment():
    experiment = ("thermodrift.core.study", "thermodrift.core.registry", "thermodrift.core.tracking",
                  "thermodrift.core.cli", "thermodrift.core.physics", "thermodrift.core.splits", "mlflow", "optuna")
    assert _offenders("core/recording", experiment) == []


def test_plugins_use_only_public_names_of_core_and_of_each_other():
    bad = []
    for path in _modules("plugins"):
        own = ".".join(["thermodrift", *path.relative_to(REPO).parts[:-1]])
        for module, names in _imports(path):
            if not module.startswith("thermodrift."):
                continue
            private_module = any(part.startswith("_") for part in module.split("."))
            if (private_module and not module.startswith(own + ".")) or any(n.startswith("_") for n in names):
                bad.append(f"{path.relative_to(REPO)}: from {module} import {', '.join(names)}")
    assert bad == []


@pytest.mark.parametrize("package", ["thermodrift.core.physics.calibration", "thermodrift.core.physics.diagnose",
                                     "thermodrift.core.recording"])
def test_plugins_use_packages_with_a_public_api_through_the_package(package):
    """Their ``__all__`` is the public door; their modules are internal."""
    bad = [f"{p.relative_to(REPO)} imports {m}" for p in _modules("plugins") for m, _ in _imports(p)
           if m.startswith(package + ".")]
    assert bad == []


def test_plugins_write_no_private_attribute_of_an_object_they_do_not_own():
    bad = []
    for path in _modules("plugins"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
                node, (ast.AugAssign, ast.AnnAssign)) else []
            for target in targets:
                for attr in ast.walk(target):
                    if (isinstance(attr, ast.Attribute) and attr.attr.startswith("_") and not attr.attr.startswith("__")
                            and not (isinstance(attr.value, ast.Name) and attr.value.id in ("self", "cls"))):
                        bad.append(f"{path.relative_to(REPO)}:{node.lineno} writes {ast.unparse(attr)}")
    assert bad == []


@pytest.mark.parametrize("folder", ["core", "plugins"])
def test_the_temperature_roles_have_one_home(folder):
    """The tuple lives in :mod:`thermodrift.core.recording.types`; every other module imports it."""
    roles = ("temperature", "ambient", "coolant_inlet", "coolant_outlet")
    homes = []
    for path in _modules(folder):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Tuple) and all(isinstance(e, ast.Constant) for e in node.elts) \
                    and tuple(e.value for e in node.elts) == roles:
                homes.append(str(path.relative_to(REPO)))
    assert homes == (["core/recording/types.py"] if folder == "core" else [])


def test_no_module_is_over_600_lines():
    long = {str(p.relative_to(REPO)): n for folder in ("core", "plugins", "compensator", "benchmarks")
            for p in _modules(folder) if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert long == {}


# ------------------------------------------------------------------------------------------------ the layers
# Source folder -> import name (pyproject.toml's package-dir), most specific first.
PACKAGES = [("core/testing", "thermodrift.testing"), ("core/optimizers", "thermodrift.optimizers"),
            ("core", "thermodrift.core"), ("plugins/hydra_sweeper", "hydra_plugins.thermodrift_sweeper"),
            ("plugins", "thermodrift.plugins"), ("compensator", "thermodrift.compensator")]
# Layer -> the module prefixes it holds; a module of ``thermodrift.core`` named by none is in ``foundation``.
LAYERS = {
    "compensator": ("thermodrift.compensator",),
    "physics": ("thermodrift.core.physics",),
    "experiment": ("thermodrift.core.splits", "thermodrift.core.study", "thermodrift.core.automl",
                   "thermodrift.core.horizons", "thermodrift.core.compensation", "thermodrift.core.deployment"),
    "tracking": ("thermodrift.core.tracking", "thermodrift.core.report"),
    "testing": ("thermodrift.testing",),
    "plugins": ("thermodrift.plugins", "hydra_plugins.thermodrift_sweeper"),
    "cli": ("thermodrift.core.cli",),
    "foundation": ("thermodrift.core", "thermodrift.optimizers"),
}
# Layer -> the layers its modules may import (besides their own); the compensator, the lowest, any layer may.
MAY_IMPORT = {
    "compensator": set(),
    "foundation": {"compensator"},
    "physics": {"foundation", "compensator"},
    "experiment": {"foundation", "physics", "compensator"},
    "tracking": {"foundation", "physics", "experiment", "compensator"},
    "testing": {"foundation", "physics", "experiment", "compensator"},
    "plugins": {"foundation", "physics", "compensator"},
    "cli": {"foundation", "physics", "experiment", "tracking", "compensator"},
}
# Third-party stacks and the only modules that may import them.
STACKS = {
    "mlflow": ("thermodrift.core.tracking", "thermodrift.core.tracking_faults", "thermodrift.core.artifacts",
               "thermodrift.core.report"),
    "hydra": ("thermodrift.core.cli", "thermodrift.core.configs", "thermodrift.core.tracking",
              "thermodrift.testing.config_checks", "hydra_plugins.thermodrift_sweeper"),
    "omegaconf": ("thermodrift.core.cli", "thermodrift.core.configs", "thermodrift.testing.config_checks",
                  "hydra_plugins.thermodrift_sweeper"),
}


def _package_modules() -> dict[str, Path]:
    out = {}
    for folder in ("core", "plugins", "compensator"):
        for path in _modules(folder):
            rel = str(path.relative_to(REPO).with_suffix(""))
            src, name = next((s, n) for s, n in PACKAGES if rel == s or rel.startswith(s + "/"))
            out[".".join([name, *rel[len(src):].strip("/").split("/")]).strip(".").removesuffix(".__init__")] = path
    return out


def _layer(module: str) -> str | None:
    for layer, prefixes in LAYERS.items():
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return layer
    return None


def _package_imports(path: Path, module: str) -> list[str]:
    """Every module ``path`` imports, relative imports resolved against its import name ``module``."""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            name = ".".join([*base, *([node.module] if node.module else [])])
            out += [f"{name}.{a.name}" for a in node.names] if node.level or name in ("thermodrift.core",) else [name]
    return out


def test_every_module_of_the_package_is_in_a_layer():
    modules = _package_modules()
    assert len(modules) > 150 and all(_layer(m) for m in modules)
    assert {_layer(m) for m in modules} == set(MAY_IMPORT)


def test_each_layer_imports_only_the_layers_below_it():
    """The compensator imports nothing of core; nothing but the CLI imports the CLI; plugins reach the experiment
    and tracking layers only through the registry (``thermodrift.testing.data``, the tiny recording, aside)."""
    modules = _package_modules()
    bad = []
    for module, path in modules.items():
        layer = _layer(module)
        for imported in _package_imports(path, module):
            if not imported.startswith(("thermodrift", "hydra_plugins.thermodrift_sweeper")):
                continue
            target = _layer(imported)
            if target in (None, layer) or target in MAY_IMPORT[layer]:
                continue
            if layer == "plugins" and imported.startswith("thermodrift.testing.data"):
                continue
            bad.append(f"{path.relative_to(REPO)} ({layer}) imports {imported} ({target})")
    assert bad == []


@pytest.mark.parametrize("stack", sorted(STACKS))
def test_each_third_party_stack_has_its_few_homes(stack):
    bad = [f"{p.relative_to(REPO)} imports {m}" for module, p in _package_modules().items()
           for m in _package_imports(p, module)
           if (m == stack or m.startswith(stack + ".")) and not any(module == h or module.startswith(h + ".")
                                                                     for h in STACKS[stack])]
    assert bad == []


def test_the_compensator_runs_on_numpy_alone():
    """What a controller loads: numpy (scipy for physics, torch for networks), nothing of the training stack;
    pandas only where ``compensate`` reads a Parquet or XLSX input table."""
    training_stack = ("thermodrift.core", "thermodrift.plugins", "thermodrift.testing", "optuna", "mlflow", "hydra",
                      "omegaconf", "sklearn", "pluggy")
    assert _offenders("compensator", training_stack) == []
    assert [o for o in _offenders("compensator", ("pandas",)) if not o.startswith("compensator/stream.py")] == []
