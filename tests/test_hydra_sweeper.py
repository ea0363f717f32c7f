"""The Hydra sweeper plugin ``hydra/sweeper=thermodrift`` on a toy Hydra app that knows nothing of thermodrift.

Sweeps run in-process (Hydra's own SweepTaskFunction) to keep the suite fast; one subprocess checks that Hydra's
plugin scan finds the sweeper without help.
"""

import copy
import importlib.util
import math
import os
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import optuna
import pytest
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.singleton import Singleton
from hydra.errors import ConfigCompositionException
from hydra.test_utils.test_utils import SweepTaskFunction
from omegaconf import OmegaConf
from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution
from optuna.trial import TrialState

import hydra_plugins.thermodrift_sweeper as plugin
from hydra_plugins.thermodrift_sweeper import _search_space
from hydra_plugins.thermodrift_sweeper._sweep import create_sampler, objective_values
from hydra_plugins.thermodrift_sweeper.config import ThermodriftSweeperConf
from hydra_plugins.thermodrift_sweeper.sweeper import ThermodriftSweeper

from support import load_file

APP = Path(__file__).parent / "hydra_toy_app" / "quadratic.py"


def _load_task():
    # registered so that hydra.sweeper.custom_search_space can name its function
    module = load_file(APP, "hydra_toy_quadratic", sys.modules.__setitem__)
    return module.main.__wrapped__  # the plain task function under @hydra.main


TASK = _load_task()


def toy_objective(x, y, n=3, act="tanh", lr=0.01):
    return (x - 1.5) ** 2 + (y + 0.5) ** 2 + 0.1 * (n - 3) ** 2 + (act != "tanh") + (math.log10(lr) + 2.0) ** 2


@pytest.fixture(autouse=True)
def sweeper_registered():
    """Hydra's singletons restored after each test; the sweeper registered explicitly so that these tests also
    run from a lenient editable install (``test_hydra_scan_finds_the_sweeper`` checks discovery on its own)."""
    state = copy.deepcopy(Singleton.get_state())
    plugin.register()
    yield
    Singleton.set_state(state)


@contextmanager
def multirun(sweep_dir: Path, *overrides: str):
    """Run the toy app as ``quadratic.py -m hydra/sweeper=thermodrift *overrides``; yield its sweep folder."""
    sweep = SweepTaskFunction()
    sweep.calling_file, sweep.task_function = str(APP), TASK
    sweep.config_path, sweep.config_name = "conf", "config"
    sweep.overrides = ["hydra/sweeper=thermodrift", *overrides]
    sweep.temp_dir = str(sweep_dir)
    with sweep:
        yield sweep_dir


def n_jobs_run(sweep_dir: Path) -> int:
    return sum(1 for p in sweep_dir.iterdir() if p.is_dir() and p.name.isdigit())


def results(sweep_dir: Path) -> dict:
    return OmegaConf.to_container(OmegaConf.load(sweep_dir / "optimization_results.yaml"))


def parse(params=None, arguments=()):
    return _search_space.parse(params or {}, list(arguments), OverridesParser.create())


# --- search space ------------------------------------------------------------------------------------------------


def test_override_syntax_maps_to_optuna_distributions():
    space = parse({"x": "interval(-5.0, 5.0)", "n": "range(1, 10)", "act": "choice(relu, tanh)",
                   "lr": "tag(log, interval(1e-4, 1e-1))", "units": "tag(log, int(interval(8, 64)))",
                   "k": "int(interval(1, 4))", "w": "range(0.0, 1.0, 0.25)", "depth": 3, "opt": "adam,sgd"},
                  ["x=interval(0, 2)", "+extra=[1,2]"])
    assert space.distributions == {
        "x": FloatDistribution(0.0, 2.0),  # the command line wins over hydra.sweeper.params
        "n": IntDistribution(1, 9),  # Hydra's range excludes its stop
        "act": CategoricalDistribution(["relu", "tanh"]),
        "lr": FloatDistribution(1e-4, 1e-1, log=True),
        "units": IntDistribution(8, 64, log=True),
        "k": IntDistribution(1, 4),
        "w": FloatDistribution(0.0, 0.75, step=0.25),
        "opt": CategoricalDistribution(["adam", "sgd"]),
    }
    assert space.fixed == ["depth=3", "+extra=[1,2]"]


def test_trial_values_become_overrides_hydra_parses_back():
    space = parse({"act": "choice('two words', [1,2], 0.5)", "lr": "tag(log, interval(1e-6, 1e-1))"})
    lines = space.overrides({"act": "two words", "lr": 1e-5}) + space.overrides({"act": "[1,2]", "lr": 0.1})
    parsed = {(o.key_or_group, repr(o.value())) for o in OverridesParser.create().parse_overrides(lines)}
    assert parsed == {("act", repr("two words")), ("lr", repr(1e-5)), ("act", repr([1, 2])), ("lr", repr(0.1))}


@pytest.mark.parametrize("params, message", [
    ({"x": "tag(lgo, interval(1e-4, 1.0))"}, "unknown tag"),
    ({"x": "tag(log, choice(1, 10))"}, "needs an interval"),
    ({"x": "tag(log, range(1, 10))"}, "log scale"),
    ({"x": "tag(log, interval(0.0, 1.0))"}, "'x=tag(log, interval(0.0, 1.0))'"),  # Optuna: log needs low > 0
])
def test_bad_search_space_is_a_clear_error(params, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        parse(params)


def test_objective_values_accept_numbers_and_sequences_only():
    assert objective_values(np.float32(2.5), 1) == [2.5]
    assert objective_values((1, 2.0), 2) == [1.0, 2.0]
    for bad, n in [(None, 1), ("0.3", 1), ((1.0,), 2), (math.inf, 1), ([1.0, math.nan], 2)]:
        with pytest.raises(ValueError):
            objective_values(bad, n)


@pytest.mark.parametrize("n_trials, n_jobs", [(-1, 1), (10, 0)])
def test_budget_and_batch_size_are_checked(n_trials, n_jobs):
    conf = {k: v for k, v in vars(ThermodriftSweeperConf(n_trials=n_trials, n_jobs=n_jobs)).items() if k != "_target_"}
    with pytest.raises(ValueError, match="n_jobs >= 1"):
        ThermodriftSweeper(**conf)


def test_sampler_gets_the_budget_when_its_factory_takes_one():
    assert create_sampler("pso", {"population_size": 4}, seed=1, n_trials=40).n_trials == 40
    assert isinstance(create_sampler("tpe", {}, seed=1, n_trials=40), optuna.samplers.TPESampler)


# --- sweeps of the toy app ---------------------------------------------------------------------------------------


def test_pso_sweep_runs_the_budget_and_beats_random_search(tmp_path):
    n_trials = 40
    with multirun(tmp_path / "pso", "hydra.sweeper.sampler=pso", "+hydra.sweeper.sampler_params.population_size=8",
                  f"hydra.sweeper.n_trials={n_trials}", "hydra.sweeper.n_jobs=8") as sweep_dir:
        assert n_jobs_run(sweep_dir) == n_trials
        found = results(sweep_dir)
    assert found["n_complete"] == n_trials and found["sampler"] == "pso"
    assert found["best_value"] == pytest.approx(toy_objective(**found["best_params"]))
    rng = np.random.default_rng(0)  # the median best of the same budget of uniform random points
    random_best = np.median([min(toy_objective(*rng.uniform(-5, 5, 2)) for _ in range(n_trials))
                             for _ in range(100)])
    assert found["best_value"] < random_best


def test_int_log_and_categorical_parameters_reach_the_jobs_typed(tmp_path):
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    with multirun(tmp_path / "sweep", "hydra.sweeper.sampler=random", "hydra.sweeper.n_trials=4",
                  "hydra.sweeper.n_jobs=4", f"hydra.sweeper.storage={storage}",
                  "n=range(1, 6)", "act=choice(relu, tanh)", "lr=tag(log, interval(1e-4, 1e-1))"):
        pass
    study = optuna.load_study(study_name="quadratic", storage=storage)
    assert len(study.trials) == 4
    for trial in study.trials:  # the toy app asserts the types; a mistyped value would make the trial FAIL
        assert trial.state == TrialState.COMPLETE
        assert trial.distributions == {"x": FloatDistribution(-5.0, 5.0), "y": FloatDistribution(-5.0, 5.0),
                                       "n": IntDistribution(1, 5), "act": CategoricalDistribution(["relu", "tanh"]),
                                       "lr": FloatDistribution(1e-4, 1e-1, log=True)}
        assert trial.value == pytest.approx(toy_objective(**trial.params))


def test_failing_jobs_are_recorded_as_fail_and_the_sweep_goes_on(tmp_path):
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    with multirun(tmp_path / "sweep", "hydra.sweeper.sampler=random", "hydra.sweeper.n_trials=6",
                  "hydra.sweeper.n_jobs=3", f"hydra.sweeper.storage={storage}", "mode=choice(ok, raise, non_finite)"):
        pass
    trials = optuna.load_study(study_name="quadratic", storage=storage).trials
    assert len(trials) == 6
    assert {t.params["mode"] for t in trials} == {"ok", "raise", "non_finite"}  # seeded: every ending occurs
    for trial in trials:
        if trial.params["mode"] == "ok":
            assert trial.state == TrialState.COMPLETE and np.isfinite(trial.value)
        else:
            assert trial.state == TrialState.FAIL
            assert ("fails on purpose" if trial.params["mode"] == "raise" else "non-finite") in \
                trial.user_attrs["failure"]


def test_interrupted_sweep_resumes_from_its_storage(tmp_path):
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    common = ("hydra.sweeper.sampler=pso", "+hydra.sweeper.sampler_params.population_size=4",
              "hydra.sweeper.n_trials=8", "hydra.sweeper.n_jobs=2", f"hydra.sweeper.storage={storage}",
              "hydra.sweeper.study_name=resumable")
    with pytest.raises(KeyboardInterrupt):  # Ctrl-C during job 3, the second job of the second batch
        with multirun(tmp_path / "first", *common, "interrupt_on_job=3"):
            pass
    before = optuna.load_study(study_name="resumable", storage=storage).trials
    assert [t.state for t in before] == [TrialState.COMPLETE] * 2 + [TrialState.FAIL] * 2
    assert all(t.user_attrs["failure"].startswith("KeyboardInterrupt") for t in before[2:])

    with multirun(tmp_path / "second", *common) as sweep_dir:
        assert n_jobs_run(sweep_dir) == 4  # only what the budget still lacks
    after = optuna.load_study(study_name="resumable", storage=storage).trials
    assert len(after) == 8 and all(t.state == TrialState.COMPLETE for t in after[4:])
    assert [(t.params, t.values) for t in after[:2]] == [(t.params, t.values) for t in before[:2]]
    assert all("pso:x" in t.system_attrs for t in after[4:])  # the swarm went on from storage


def test_custom_search_space_adds_conditional_parameters(tmp_path):
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    with multirun(tmp_path / "sweep", "hydra.sweeper.sampler=random", "hydra.sweeper.n_trials=6",
                  "hydra.sweeper.n_jobs=6", f"hydra.sweeper.storage={storage}", "act=choice(relu, tanh)",
                  "hydra.sweeper.custom_search_space=hydra_toy_quadratic.relu_learning_rate"):
        pass
    trials = optuna.load_study(study_name="quadratic", storage=storage).trials
    assert {t.params["act"] for t in trials} == {"relu", "tanh"}
    for trial in trials:
        assert trial.state == TrialState.COMPLETE
        assert ("lr" in trial.params) == (trial.params["act"] == "relu")
        assert trial.value == pytest.approx(toy_objective(**trial.params))


def test_multi_objective_sweep(tmp_path):
    with multirun(tmp_path / "sweep", "hydra.sweeper.sampler=random", "hydra.sweeper.n_trials=4",
                  "hydra.sweeper.n_jobs=4", "hydra.sweeper.direction=[minimize,minimize]",
                  "objectives=2") as sweep_dir:
        found = results(sweep_dir)
    assert found["directions"] == ["minimize", "minimize"] and found["n_complete"] == 4
    assert found["best_trials"] and all(len(t["values"]) == 2 for t in found["best_trials"])


def test_a_search_space_the_app_cannot_take_fails_before_any_job(tmp_path):
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    with pytest.raises(ConfigCompositionException):
        with multirun(tmp_path / "sweep", f"hydra.sweeper.storage={storage}", "no_such_key=interval(0, 1)"):
            pass
    assert optuna.get_all_study_names(storage) == []


# --- discovery ---------------------------------------------------------------------------------------------------


def test_hydra_scan_finds_the_sweeper(tmp_path):
    """Hydra finds the sweeper by walking ``hydra_plugins`` on disk, as after ``pip install .`` (what CI does).
    A lenient editable install serves the package through an import hook the walk cannot list; there the test
    lays the package out as an install would, on PYTHONPATH."""
    env = dict(os.environ)
    installed = Path(importlib.util.find_spec("hydra_plugins.thermodrift_sweeper").origin).parent
    if installed.parts[-2:] != ("hydra_plugins", "thermodrift_sweeper"):
        layout = tmp_path / "hydra_plugins" / "thermodrift_sweeper"
        layout.parent.mkdir()
        layout.symlink_to(installed, target_is_directory=True)
        env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env.get("PYTHONPATH", "")])
    code = ("from hydra.core.plugins import Plugins\n"
            "from hydra.core.config_store import ConfigStore\n"
            "from hydra.plugins.sweeper import Sweeper\n"
            "print(sorted(c.__name__ for c in Plugins.instance().discover(Sweeper)))\n"
            "print(sorted(ConfigStore.instance().list('hydra/sweeper')))\n"
            "import sys; print('optuna' in sys.modules, 'thermodrift.core.registry' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    sweepers, configs, heavy = out.splitlines()
    assert "ThermodriftSweeper" in sweepers and "thermodrift.yaml" in configs
    assert heavy == "False False"  # Hydra imports every plugin at start-up: ours stays light until it sweeps
