"""`thermodrift run --help` and the override check: options read from the registry, typos answered in one line
with the closest right name; `thermodrift plugins` as a table with a description per component."""

from __future__ import annotations

import subprocess
import sys

import pytest

from thermodrift.core import registry
from thermodrift.core.cli import run_options
from thermodrift.core.errors import InputError


def test_help_lists_every_groups_options_from_the_registry_and_the_keys_with_meaning(tmp_path, cli):
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
    assert "transfer_function*" in text and "tpe*" in text  # defaults marked
    n_trials = next(ln for ln in text.splitlines() if ln.strip().startswith("n_trials "))
    assert "20" in n_trials and "Optuna trials per fold" in n_trials
    assert "(µm)" in next(ln for ln in text.splitlines() if ln.strip().startswith("targets "))
    assert "examples:" in text and "thermodrift run -m" in text

    proc = cli(tmp_path, "run", "--help")
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


def test_the_cli_exits_2_with_one_line(tmp_path, cli):
    proc = cli(tmp_path, "run", "model=mrl")
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "did you mean 'mlr'?" in proc.stderr and "options: bp" in proc.stderr


def test_plugins_prints_a_table_with_headers_and_a_description_per_component(tmp_path, cli):
    proc = cli(tmp_path, "plugins")
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stdout.splitlines() if ln.strip()]
    assert lines[0].split() == ["KIND", "NAME", "ORIGIN", "DESCRIPTION"]
    rows = {ln.split()[1]: ln for ln in lines[1:] if not ln.startswith("failed")}
    assert "Keep every temperature channel." in rows["all"]
    assert "Tree-structured Parzen estimator" in rows["tpe"]
    assert "radiation" in rows["radiation"] and "Base class" not in rows["radiation"]  # not the inherited doc
    assert all(len(ln.split(None, 3)) == 4 for ln in rows.values())  # every component has a description


PROBE = ("import sys; from thermodrift.core.cli import main; rc = main({argv!r}); "
         "print(rc, *sorted(m for m in {heavy!r} if m in sys.modules))")
HEAVY = ("torch", "mlflow", "hydra", "optuna", "sklearn", "pandas", "thermodrift.plugins.models",
         "thermodrift.core.cli.run")


@pytest.mark.parametrize("argv,message", [(["run", "model=mrl"], "(did you mean 'mlr'?)"),
                                          (["run", "-m", "n_trial=5"], "(did you mean 'n_trials'?)"),
                                          (["run", "model=mlr", "model.params.alph=2"],
                                           "(did you mean 'model.params.alpha'?)")])
def test_a_typo_is_answered_before_plugins_hydra_mlflow_or_torch_load(tmp_path, argv, message, cli):
    env = cli.env(THERMODRIFT_CACHE_DIR=str(tmp_path / "cache"))
    # the first call after an install loads the plugins once and saves their listing (as `run --help` does)
    first = subprocess.run([sys.executable, "-c", PROBE.format(argv=argv, heavy=HEAVY)], capture_output=True,
                           text=True, timeout=300, env=env, cwd=tmp_path)
    assert first.stdout.split()[0] == "2" and message in first.stderr
    again = subprocess.run([sys.executable, "-c", PROBE.format(argv=argv, heavy=HEAVY)], capture_output=True,
                           text=True, timeout=300, env=env, cwd=tmp_path)
    assert again.stdout.split() == ["2"], again.stdout  # exit code 2, and none of the heavy modules imported
    assert again.stderr.count("\n") == 1 and message in again.stderr


def test_help_text_is_plain_and_complete(tmp_path, cli):
    text = run_options.help_text(registry.default())
    keys = {k.path: k.doc for k in run_options.keys()}
    assert keys["search_space"].endswith("'search_space={alpha: {type: float, low: 0.01, high: 10, log: true}}'")
    assert "0 = untuned" in keys["n_trials"]  # a comment continued on the next line is part of the key's
    assert "(nothing to tune) or\n" not in text and "log: true}}'" in text
    assert all(len(line) <= 110 for line in text.splitlines() if not line.startswith("warning:"))
    top = cli(tmp_path, "--help")
    plugins = cli(tmp_path, "plugins")
    for out in (text, top.stdout, plugins.stdout):
        assert "``" not in out and ":class:`" not in out and ":func:`" not in out and ":mod:`" not in out
    assert "The thermodrift command line" in top.stdout
    described = {ln.split()[1]: ln.split(None, 3)[3] for ln in plugins.stdout.splitlines()[1:]
                 if len(ln.split(None, 3)) == 4}
    assert not [n for n, d in described.items() if d.lower().startswith("see ")]  # a pointer is no description
    assert "LSTM" in described["cnn_lstm"] and "Fourier-KAN" in described["dltk"]


def test_plain_renders_restructuredtext_roles_and_literals():
    from thermodrift.core.cli import plain

    assert plain("The ``thermodrift`` command line") == "The thermodrift command line"
    assert plain("see :class:`~thermodrift.core.registry.Registry`") == "see Registry"
    assert plain(":mod:`thermodrift.core.configs` and :func:`load <thermodrift.core.registry.load>`") == \
        "thermodrift.core.configs and load"
    assert plain("`thermodrift run` and **all** of `Optuna`_; * = default") == \
        "thermodrift run and all of Optuna; * = default"
