"""The job pipeline in-process: inputs, failed trials, determinism, resume, labelled protocols."""

import numpy as np
import optuna
import pytest

from thermodrift.core import registry
from thermodrift.core.study import Job, JobSpec, model_inputs
from thermodrift.plugins.models.mlr import MLR
from thermodrift.plugins.models.persistence import Persistence
from thermodrift.testing.data import tiny_recording


class Flaky(MLR):
    """MLR that fails for large alpha: the study must record those trials as failed and go on."""

    def _fit(self, X, y):
        if self.alpha > 1.0:
            raise RuntimeError("alpha too large for this test")
        super()._fit(X, y)


@pytest.fixture()
def reg(monkeypatch):
    loaded = registry.load()
    loaded.add("model", "flaky", Flaky, origin="tests", module=__name__)
    monkeypatch.setattr(registry, "_DEFAULT", loaded)
    return loaded


@pytest.fixture(scope="module")
def rec():
    return tiny_recording(seed=0)


def spec(**kw):
    base = dict(dataset="tiny", model="mlr", selector="correlation_top_k", n_trials=6, storage=None, progress=False)
    return JobSpec(**{**base, **kw})


def test_model_inputs_carry_roles(rec):
    class NeedsSpeed(Persistence):
        extra_input_roles = ("speed", "ambient")

    X = model_inputs(rec, ["T_column"], NeedsSpeed, ["disp_z_um"])
    assert list(X.columns) == ["T_column", "speed_rpm", "T_ambient", "lag1:disp_z_um"]
    assert X.iloc[10:20].attrs["roles"] == {"T_column": "temperature", "speed_rpm": "speed",
                                            "T_ambient": "ambient", "lag1:disp_z_um": "target_history"}
    assert (X["lag1:disp_z_um"].to_numpy()[1:] == rec.data["disp_z_um"].to_numpy()[:-1]).all()


def test_failed_trials_are_recorded_and_the_study_goes_on(reg, rec):
    space = {"alpha": {"type": "float", "low": 1e-3, "high": 100.0, "log": True}}
    result = Job(spec(model="flaky", model_search_space=space, n_trials=12, optimizer="random")).run(rec)
    states = [t.state for t in result.study.trials]
    assert len(states) == 12
    assert optuna.trial.TrialState.FAIL in states and optuna.trial.TrialState.COMPLETE in states
    assert result.best_params["alpha"] <= 1.0


def test_same_seed_same_result_and_baselines_beside_the_model(reg, rec):
    a = Job(spec(seed=5)).run(rec)
    b = Job(spec(seed=5)).run(rec)
    assert a.best_params == b.best_params and a.selected == b.selected
    np.testing.assert_array_equal(a.folds[0].predictions["model"], b.folds[0].predictions["model"])
    assert set(a.folds[0].metrics) == {"model", "persistence", "mlr"}
    assert a.protocol == "honest"


def test_rerun_with_same_storage_resumes(reg, rec, tmp_path):
    storage = f"sqlite:///{tmp_path / 'optuna.db'}"
    first = Job(spec(storage=storage, n_trials=3)).run(rec)
    numbers = [(t.number, t.value) for t in first.study.trials]
    second = Job(spec(storage=storage, n_trials=5)).run(rec)
    assert len(second.study.trials) == 5
    assert [(t.number, t.value) for t in second.study.trials[:3]] == numbers


def test_paper_protocol_is_labelled(reg, rec):
    with pytest.warns(UserWarning, match="paper protocol"):
        result = Job(spec(split="shuffled", n_trials=2)).run(rec)
    assert result.protocol == "paper"


def test_a_model_without_search_space_runs_one_trial(reg, rec):
    result = Job(spec(model="persistence", n_trials=10)).run(rec)
    assert len(result.study.trials) == 1
    np.testing.assert_allclose(result.summary_metrics("model")["rmse"], result.summary_metrics("persistence")["rmse"])
    assert result.same_as() == "persistence"
    assert Job(spec(n_trials=0, model_params={"alpha": 100.0})).run(rec).same_as() is None


@pytest.mark.parametrize("optimizer", ["pso", "pso_constriction", "rbmox"])
def test_the_study_budget_reaches_samplers_with_schedules(reg, rec, optimizer):
    result = Job(spec(optimizer=optimizer, n_trials=7)).run(rec)
    assert result.study.sampler.n_trials == 7
    assert registry.create_sampler(optimizer, seed=0, n_trials=9).n_trials == 9


@pytest.mark.parametrize("pruner, kind", [("median", optuna.pruners.MedianPruner), ("none", optuna.pruners.NopPruner),
                                           ("hyperband", optuna.pruners.HyperbandPruner)])
def test_the_pruner_setting_reaches_the_study(reg, rec, pruner, kind):
    assert isinstance(Job(spec(pruner=pruner, n_trials=2)).run(rec).study.pruner, kind)


def test_a_misspelt_pruner_is_bad_input_before_any_work(reg, rec):
    from thermodrift.core.errors import InputError

    with pytest.raises(InputError, match="did you mean 'median'") as err:
        Job(spec(pruner="medain")).run(object())  # not a recording: nothing is read before the check
    assert "\n" not in str(err.value)


def test_a_paper_protocol_job_and_its_export_warn_once(reg, rec):
    import warnings

    from thermodrift.core import deployment

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        deployment.limits(Job(spec(split="shuffled", n_trials=2)).run(rec))
    assert sum("paper protocol" in str(w.message) for w in caught) == 1


def test_unknown_split_is_bad_input(reg, rec):
    from thermodrift.core.errors import InputError

    with pytest.raises(InputError, match="unknown split"):
        Job(spec(split="random_rows")).run(rec)


def test_each_fold_has_its_own_study_that_resumes(reg, rec, tmp_path):
    storage = f"sqlite:///{tmp_path / 'optuna.db'}"
    first = Job(spec(split="forward_chaining", storage=storage, n_trials=2)).run(rec)
    names = [f.study.study_name for f in first.folds]
    assert len(names) == 3 and len(set(names)) == 3 and all(n.endswith(f"-fold{k}of3") for k, n in
                                                            enumerate(names, 1))
    assert all(len(f.study.trials) == 2 and f.trials_before == 0 for f in first.folds)
    said = []
    second = Job(spec(split="forward_chaining", storage=storage, n_trials=3), say=said.append).run(rec)
    assert [f.study.study_name for f in second.folds] == names
    assert all(len(f.study.trials) == 3 and f.trials_before == 2 for f in second.folds)
    assert said == [f"study {n} resumed: 2 of 3 trials complete, 1 to run" for n in names]


def test_zero_trials_runs_the_model_untuned_on_its_defaults(reg, rec):
    result = Job(spec(n_trials=0, model_params={"alpha": 3.0})).run(rec)
    assert result.study is None and result.best_params == {"alpha": 3.0}
    assert result.model.alpha == 3.0 and np.isfinite(result.valid_rmse)
    mlr_default = Job(spec(n_trials=0, model="mlr", model_params={})).run(rec)
    # untuned MLR on its defaults is the MLR baseline
    np.testing.assert_array_equal(mlr_default.folds[0].predictions["model"], mlr_default.folds[0].predictions["mlr"])


def test_an_empty_search_space_runs_one_trial_on_the_defaults(reg, rec):
    result = Job(spec(model_search_space={}, n_trials=5)).run(rec)
    assert len(result.study.trials) == 1 and result.best_params == {}
