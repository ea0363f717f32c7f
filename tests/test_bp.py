"""Model ``bp``: learns a nonlinear thermal relation, is reproducible, pickles, clones, matches its YAML."""

import pickle

import numpy as np
import optuna
import pandas as pd
import pytest
from sklearn.base import clone

from thermodrift.core import configs, registry
from thermodrift.core.search_space import distributions
from thermodrift.core.training import DivergedError, reporting
from thermodrift.plugins.models.bp import BPNetwork

SAMPLE_S = 60.0


pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _recording(n=480, seed=0):
    """Spindle speed steps drive two first-order lags (τ 20 and 80 min); drift is nonlinear in them."""
    rng = np.random.default_rng(seed)
    speed_rpm = np.repeat([0, 3000, 6000, 1500, 0, 4500, 6000, 2000, 0, 3000, 6000, 1000], n // 12)
    rise_K = 20 * (speed_rpm / 6000) ** 1.5
    a_fast, a_slow = np.exp(-SAMPLE_S / 1200), np.exp(-SAMPLE_S / 4800)
    fast, slow = np.zeros(n), np.zeros(n)
    for i in range(1, n):  # exact step response of dT/dt = (u - T)/τ for piecewise-constant u
        fast[i] = a_fast * fast[i - 1] + (1 - a_fast) * rise_K[i - 1]
        slow[i] = a_slow * slow[i - 1] + (1 - a_slow) * 0.5 * rise_K[i - 1]
    index = pd.Index(np.arange(n) * SAMPLE_S, name="time_s")
    X = pd.DataFrame({"T_bearing": 20 + fast + 0.3 * slow, "T_column": 20 + slow + 0.1 * fast}, index=index)
    X += rng.normal(0, 0.02, X.shape)
    drift_um = 2.0 * fast + 0.15 * fast**2 - 3 * np.tanh(slow / 4) * slow
    y = pd.DataFrame({"disp_z_um": drift_um + rng.normal(0, 0.2, n)}, index=index)
    return X, y


FAST = dict(epochs=140, t0=20, t_mult=2, lr_max=3e-2, device="cpu")


def _fast(**trainer):
    """A BP network trained briefly on CPU, with ``trainer`` settings on top of FAST."""
    return BPNetwork(trainer={**FAST, **trainer})


def test_learns_nonlinear_drift_far_better_than_a_constant():
    X, y = _recording()
    n_train = 360
    model = _fast().fit(X[:n_train], y[:n_train])
    truth = y[n_train:].to_numpy()
    rmse_model = np.sqrt(np.mean((model.predict(X[n_train:]) - truth) ** 2))
    rmse_constant = np.sqrt(np.mean((y[:n_train].to_numpy().mean() - truth) ** 2))
    assert rmse_model < 0.2 * rmse_constant
    report = model.train_report_
    assert report.epochs_run == 140 and report.best_epoch in report.cycle_ends + [140]
    assert np.isfinite([report.grad_norm_mean, report.grad_norm_max, report.clipped_fraction]).all()


def test_same_seed_gives_identical_predictions():
    X, y = _recording()
    trainer = dict(FAST, epochs=20, batch_size=64)
    a = BPNetwork(trainer=trainer, random_state=3).fit(X, y).predict(X)
    b = BPNetwork(trainer=trainer, random_state=3).fit(X, y).predict(X)
    c = BPNetwork(trainer=trainer, random_state=4).fit(X, y).predict(X)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_huge_learning_rate_raises_diverged():
    X, y = _recording()
    with pytest.raises(DivergedError):
        _fast(lr_max=1e6, epochs=40).fit(X, y)


def test_always_pruning_trial_stops_fit():
    X, y = _recording()
    study = optuna.create_study(pruner=_AlwaysPrune())
    trial = study.ask()
    with reporting(trial), pytest.raises(optuna.TrialPruned):
        _fast().fit(X, y)
    study.tell(trial, state=optuna.trial.TrialState.PRUNED)
    assert list(study.trials[0].intermediate_values) == [20]


class _AlwaysPrune(optuna.pruners.BasePruner):
    def prune(self, study, trial):
        return True


def test_pickle_round_trip_and_clone():
    X, y = _recording()
    model = _fast(epochs=20).fit(X, y)
    restored = pickle.loads(pickle.dumps(model))
    assert np.array_equal(restored.predict(X), model.predict(X))
    assert restored.train_report_ == model.train_report_
    fresh = clone(model)
    assert fresh.get_params() == model.get_params()
    assert not hasattr(fresh, "state_dict_")


@pytest.mark.parametrize("params", BPNetwork.get_test_params())
def test_test_params_fit_fast_with_two_outputs(params):
    X, y = _recording(n=120)
    y2 = pd.concat([y, (-0.5 * y).rename(columns={"disp_z_um": "disp_x_um"})], axis=1)
    model = BPNetwork(**params).set_params(trainer__device="cpu").fit(X, y2)
    assert model.predict(X).shape == (120, 2)
    assert model.train_report_.epochs_run == params["trainer"]["epochs"]


def test_registered_and_config_mirrors_class_defaults():
    assert isinstance(registry.load().create("model", "bp", hidden_units=5), BPNetwork)
    conf = configs.node(registry.get("model", "bp"))  # the config `thermodrift run model=bp` composes
    assert conf["name"] == "bp"
    # random_state is left out so that the run's `seed` reaches the model; the trainer block lists every field
    assert "random_state" not in conf["params"]
    def resolved(model):  # every parameter, trainer fields as trainer__<field>
        return {k: v for k, v in model.get_params().items() if k != "trainer"}

    assert resolved(BPNetwork(**conf["params"])) == resolved(BPNetwork())
    assert conf["search_space"] == BPNetwork.search_space()
    space = distributions(conf["search_space"])
    assert {"hidden_layers", "hidden_units", "trainer__lr_max", "trainer__eta_min_ratio", "trainer__t0",
            "trainer__t_mult", "trainer__clip_norm"} <= set(space)
    assert space["hidden_units"].low == 3 and space["hidden_units"].high == 13


def test_bad_activation_is_rejected():
    X, y = _recording(n=60)
    with pytest.raises(ValueError, match="activation"):
        BPNetwork(activation="swish", trainer={"epochs": 1}).fit(X, y)


def test_trainer_fields_are_nested_params_that_round_trip_through_clone_and_create():
    model = BPNetwork(hidden_units=5)
    params = model.get_params()
    assert params["trainer"] is None and params["trainer__lr_max"] == 1e-2 and params["trainer__epochs"] == 300
    model.set_params(trainer__lr_max=0.05, trainer__epochs=7)
    assert model.trainer == {"lr_max": 0.05, "epochs": 7}
    assert model.trainer_settings().lr_max == 0.05 and model.trainer_settings().t0 == 20
    fresh = clone(model)
    assert fresh.get_params() == model.get_params() and fresh.trainer is not model.trainer
    assert BPNetwork().trainer is None  # the class default was not changed in place
    built = registry.load().create("model", "bp", hidden_units=4, trainer={"epochs": 3}, trainer__t0=2)
    assert built.trainer_settings().epochs == 3 and built.trainer_settings().t0 == 2
    with pytest.raises(ValueError, match="unknown trainer settings"):
        BPNetwork(trainer={"lr": 0.1}).trainer_settings()
