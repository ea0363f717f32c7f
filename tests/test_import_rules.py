"""Import rules and the shape of the code: data knows no experiment, physics imports neither tracking nor the
CLI, plugins use only public names of core and of each other, one home for the temperature roles, no module over
600 lines. Read from the source (every import, also those inside functions), so nothing needs importing."""

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


def test_no_module_in_core_or_plugins_is_over_600_lines():
    long = {str(p.relative_to(REPO)): n for folder in ("core", "plugins") for p in _modules(folder)
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert long == {}
