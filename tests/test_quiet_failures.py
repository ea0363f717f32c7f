"""Broken plugins are named and isolated; failed trials are one line each, with the traceback kept aside."""

import logging
import os

import optuna
import pytest

from thermodrift.core import trial_faults
from thermodrift.testing.data import tiny_recording

FAULTS = {"import_error": "import no_such_module_anywhere", "system_exit": "import sys\nsys.exit('bye from plugin')",
          "runtime_error": "raise RuntimeError('plugin init broke')"}


def _fake_distribution(site, name: str, body: str) -> None:
    """An installed-looking distribution ``broken-<name>`` whose thermodrift entry point runs ``body``."""
    (site / f"broken_{name}.py").write_text(body + "\n", encoding="utf-8")
    info = site / f"broken_{name}-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: broken-{name}\nVersion: 1.0\n", encoding="utf-8")
    (info / "entry_points.txt").write_text(f"[thermodrift]\nbroken = broken_{name}\n", encoding="utf-8")


@pytest.fixture()
def broken_site(tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    for name, body in FAULTS.items():
        _fake_distribution(site, name, body)
    env = {"PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    tiny_recording(seed=0).write(tmp_path / "tiny.csv", tmp_path / "tiny.yaml")
    return tmp_path, env


def test_broken_plugins_are_named_by_plugins_and_run_and_the_rest_works(broken_site, cli):
    cwd, env = broken_site
    listing = cli(cwd, "plugins", env=env, timeout=300)
    assert listing.returncode == 0, listing.stderr
    out = cli(cwd, "run", "dataset=recording_file", "dataset.params.table=tiny.csv",
              "dataset.params.manifest=tiny.yaml", "progress=false", "model=mlr", "n_trials=2", env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    warnings = [ln for ln in out.stderr.splitlines() if ln.startswith("thermodrift: warning: plugin")]
    for name in FAULTS:
        assert f"broken-{name}" in listing.stdout + listing.stderr
        assert any(f"broken-{name}" in ln for ln in warnings), out.stderr
    assert any("SystemExit: bye from plugin" in ln for ln in warnings)
    assert "Traceback" not in out.stderr


def test_a_failed_trial_is_one_line_with_its_traceback_in_attrs_and_log(tmp_path, capfd):
    def objective(trial):
        x = trial.suggest_float("x", -1, 1)
        if trial.number % 2:
            raise ValueError(f"odd trial {trial.number} refused")
        return x * x

    log = trial_faults.log_to(tmp_path)
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    study.optimize(trial_faults.reporting(objective), n_trials=4, catch=(Exception,))
    for handler in trial_faults.LOGGER.handlers:
        handler.flush()
    err = capfd.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines == ["thermodrift: trial 1 failed: ValueError: odd trial 1 refused",
                     "thermodrift: trial 3 failed: ValueError: odd trial 3 refused"]
    failed = [t for t in study.trials if t.state == optuna.trial.TrialState.FAIL]
    assert [t.number for t in failed] == [1, 3]
    assert all("Traceback" in t.user_attrs["traceback"] and "refused" in t.user_attrs["fail_reason"] for t in failed)
    text = log.read_text(encoding="utf-8")
    assert text.count("Traceback") == 2 and "odd trial 3 refused" in text
    for handler in list(trial_faults.LOGGER.handlers):
        trial_faults.LOGGER.removeHandler(handler)
        handler.close()
    logging.getLogger("optuna.study._optimize").setLevel(logging.NOTSET)
