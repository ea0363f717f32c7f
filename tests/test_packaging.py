"""The install layout: namespaced import names, no top-level squatting, every config group packaged."""

import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_namespaced_imports_from_another_folder(tmp_path):
    ok = subprocess.run([sys.executable, "-c", "import thermodrift.core, thermodrift.plugins.models, thermodrift.conf"],
                        cwd=tmp_path, capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    for squat in ("core", "plugins", "conf"):
        bad = subprocess.run([sys.executable, "-c", f"import {squat}"], cwd=tmp_path, capture_output=True, text=True)
        assert bad.returncode != 0 and "ModuleNotFoundError" in bad.stderr


def test_every_conf_group_is_a_listed_package():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    packages = set(meta["tool"]["setuptools"]["packages"])
    groups = {p.name for p in (ROOT / "conf").iterdir() if p.is_dir() and p.name != "__pycache__"}
    assert groups, "conf/ has no config groups"
    assert {f"thermodrift.conf.{g}" for g in groups} <= packages
    listed = {p.split(".")[-1] for p in packages if p.startswith("thermodrift.conf.")}
    assert listed == groups
    data = meta["tool"]["setuptools"]["package-data"]
    assert all(data.get(f"thermodrift.conf.{g}") == ["*.yaml"] for g in groups)


def test_every_plugin_folder_is_a_listed_package():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    packages = set(meta["tool"]["setuptools"]["packages"])
    folders = {p.name for p in (ROOT / "plugins").iterdir() if (p / "__init__.py").exists()}
    mapped = {"hydra_sweeper": "hydra_plugins.thermodrift_sweeper"}
    assert {mapped.get(f, f"thermodrift.plugins.{f}") for f in folders} <= packages


def test_entry_points_name_existing_modules():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    dirs = meta["tool"]["setuptools"]["package-dir"]
    for name, target in meta["project"]["entry-points"]["thermodrift"].items():
        package = max((p for p in dirs if target == p or target.startswith(p + ".")), key=len)
        rel = ROOT / dirs[package] / target[len(package):].lstrip(".").replace(".", "/")
        assert rel.with_suffix(".py").exists() or (rel / "__init__.py").exists(), (
            f"entry point {name} -> {target} has no module")


# What the README's commands write into the working folder: git must ignore every one of them.
WRITTEN = ["mlflow.db", "mlflow.db.lock", "thermodrift.optuna.db", "thermodrift.optuna.db.lock",
           "outputs/2026-11-26/10-00-00/run.log", "multirun/2026-11-26_10-00-00_abc123/0/job.json",
           "mlartifacts/1/abc/artifacts/figures/a.png", "mlruns/0/meta.yaml", "reports/sweep/report.md",
           "runs/calibrate/calibration.json", "sim/motorized_spindle_s3.csv"]


def test_gitignore_covers_what_commands_write(tmp_path):
    subprocess.run(["git", "init", "-q", str(tmp_path)], check=True)
    shutil.copy(ROOT / ".gitignore", tmp_path / ".gitignore")
    out = subprocess.run(["git", "check-ignore", "--no-index", *WRITTEN, "core/report.py", "conf/config.yaml"],
                         cwd=tmp_path, capture_output=True, text=True)
    assert out.stdout.split() == WRITTEN  # every output ignored, the sources not
