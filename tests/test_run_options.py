"""`thermodrift run --help` and the override check: options read from the registry, typos answered in one line
with the closest right name; `thermodrift plugins` as a table with a description per component."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from thermodrift.core import registry
from thermodrift.core.cli import run_options
from thermodrift.core.errors import InputError

EXE = [sys.executable, "-m", "thermodrift.core.cli"]


def _thermodrift(cwd, *args):
    env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true"}
    return subprocess.run([*EXE, *args], cwd=cwd, capture_output=True, text=True, timeout=300, env=env)


def test_help_lists_every_groups_options_from_the_registry_and_the_keys_with_meaning(tmp_path):
    reg = registry.default()
    reg_extra = registry.Registry(searchpaths=list(reg.searchpaths))
    reg_extra.components = {k: dict(v) for k, v in reg.components.items()}
    reg_extra.add("selector", "only_in_the_registry", lambda: None)
    text = run_options.help_text(reg_extra)
    for group in ("dataset", "split", "selector", "model", "optimizer", "experiment"):
        assert f"\n  {group}" in text
    for kind in ("selector", "model", "optimizer", "dataset"):
        assert all(name in text for name in reg.names(kind)), kind
    assert "only_in_the_registry" in text and "pso_s1" in text and "forward_chaining" in text
    assert "mlr*" in text and "tpe*" in text  # defaults marked
    n_trials = next(ln for ln in text.splitlines() if ln.strip().startswith("n_trials "))
    assert "20" in n_trials and "Optuna trials per fold" in n_trials
    assert "(µm)" in next(ln for ln in text.splitlines() if ln.strip().startswith("targets "))
    assert "examples:" in text and "thermodrift run -m" in text

    proc = _thermodrift(tmp_path, "run", "--help")
    assert proc.returncode == 0 and proc.stdout.startswith("usage: thermodrift run") and "Hydra" not in proc.stdout[:200]


@pytest.mark.parametrize("overrides,message", [
    (["model=mrl"], "unknown model 'mrl' (did you mean 'mlr'?); options: bp, "),
    (["-m", "model=mlr,bpp"], "unknown model 'bpp' (did you mean 'bp'?)"),
    (["n_trial=5"], "unknown key 'n_trial' (did you mean 'n_trials'?)"),
    (["tracking.urii=x"], "did you mean 'tracking.uri'?"),
    (["selector.parms.k=3"], "did you mean 'selector.params'?"),
    (["model=mlr", "model.params.alpah=2"], "model 'mlr' has no parameter 'alpah' (did you mean 'model.params.alpha'?)"),
    (["optimizer=pso_s1", "optimizer.params.c3=1"], "optimizer 'pso_s1' has no parameter 'c3'"),
    (["experiment=fl_thermal_5000rpm_heldout", "dataset.params.seed=1"], "dataset 'fl_thermal' has no parameter"),
])
def test_a_typo_is_one_line_with_the_closest_right_name(overrides, message):
    with pytest.raises(InputError) as err:
        run_options.check_overrides([o for o in overrides if o != "-m"], registry.default())
    assert message in str(err.value) and "\n" not in str(err.value) and "+n_trial" not in str(err.value)


@pytest.mark.parametrize("overrides", [
    ["model=bp", "model.params.trainer.epochs=3"], ["optimizer=pso_s1", "optimizer.params.c1=1.5"],
    ["ablation=x"], ["+extra=1"], ["~targets"], ["hydra.run.dir=out"], ["model=glob(*)"], ["model=mlr,bp"],
    ["selector.params.k=6"], ["dataset=recording_file", "dataset.params.table=x.csv"],
    ["hydra/sweeper=thermodrift"], ["optuna.storage=null"], ["model.search_space.alpha.low=0.1"],
    ["experiment=fl_thermal_5000rpm_heldout", "dataset.params.path=x.xlsx", "split.params.train_end_h=3"],
])
def test_valid_overrides_pass(overrides):
    run_options.check_overrides(overrides, registry.default())


def test_the_cli_exits_2_with_one_line(tmp_path):
    proc = _thermodrift(tmp_path, "run", "model=mrl")
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "did you mean 'mlr'?" in proc.stderr and "options: bp" in proc.stderr


def test_plugins_prints_a_table_with_headers_and_a_description_per_component(tmp_path):
    proc = _thermodrift(tmp_path, "plugins")
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stdout.splitlines() if ln.strip()]
    assert lines[0].split() == ["KIND", "NAME", "ORIGIN", "DESCRIPTION"]
    rows = {ln.split()[1]: ln for ln in lines[1:] if not ln.startswith("failed")}
    assert "Keep every temperature channel." in rows["all"]
    assert "Tree-structured Parzen estimator" in rows["tpe"]
    assert "radiation" in rows["radiation"] and "Base class" not in rows["radiation"]  # not the inherited doc
    assert all(len(ln.split(None, 3)) == 4 for ln in rows.values())  # every component has a description
