"""The shared torch trainer: SGDR read points, early stopping, clipping, divergence guard, pruning, seeds."""

import math

import numpy as np
import optuna
import pytest
import torch
from torch import nn
from torch.optim.optimizer import register_optimizer_step_pre_hook

from thermodrift.core.training import (
    DivergedError, Standardizer, TrainerSettings, cycle_ends, predict, reporting, train, trainer_search_space)


pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _data(n=240, seed=0):
    """Smooth nonlinear map of two inputs (°C-like) to one output (µm-like), in time order."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 4 * np.pi, n)
    X = np.column_stack([20 + 5 * np.sin(t), 25 + 3 * np.cos(0.5 * t)])
    y = 4 * (X[:, :1] - 20) + 0.5 * (X[:, 1:] - 25) ** 2 + rng.normal(0, 0.1, (n, 1))
    return X, y


def _mlp():
    return nn.Sequential(nn.Linear(2, 8), nn.Tanh(), nn.Linear(8, 1))


def _config(**kw):
    base = dict(lr_max=3e-2, epochs=21, t0=3, t_mult=2, patience=None, validation_fraction=0.2, device="cpu")
    return TrainerSettings(**{**base, **kw})


class _AlwaysPrune(optuna.pruners.BasePruner):
    def prune(self, study, trial):
        return True


def test_cycle_ends_follow_t0_and_t_mult():
    assert cycle_ends(3, 2, 21) == [3, 9, 21]
    assert cycle_ends(3, 2, 20) == [3, 9]
    assert cycle_ends(5, 1, 17) == [5, 10, 15]
    assert cycle_ends(50, 2, 10) == []


def test_standardizer_round_trips_and_keeps_constant_features_finite():
    a = np.column_stack([np.arange(10.0), np.full(10, 7.0)])
    s = Standardizer.fit(a)
    z = s.transform(a)
    assert np.allclose(z[:, 0].mean(), 0) and np.isclose(z[:, 0].std(), 1)
    assert np.all(z[:, 1] == 0)
    assert np.allclose(s.inverse(z), a)
    windows = np.stack([a, a + 1])  # (2, 10, 2): statistics over all axes but the feature axis
    assert Standardizer.fit(windows).mean.shape == (2,)


def test_config_rejects_invalid_settings():
    with pytest.raises(ValueError, match="t_mult"):
        TrainerSettings(t_mult=0)
    with pytest.raises(ValueError, match="validation_fraction"):
        TrainerSettings(validation_fraction=0.9)
    with pytest.raises(ValueError, match="loss"):
        TrainerSettings(loss="hinge")


def test_training_fits_and_keeps_the_best_read_point():
    X, y = _data()
    result = train(_mlp, X, y, _config())
    report = result.report
    assert report.epochs_run == 21 and report.steps == 21
    assert sorted(report.val_rmse_um) == [3, 9, 21]
    assert report.best_val_rmse_um == min(report.val_rmse_um.values())
    # The kept weights reproduce the best validation RMSE on the chronological tail.
    module = _mlp()
    module.load_state_dict(result.state_dict)
    pred = predict(module, X[-48:], result.x_scaler, result.y_scaler, torch.device("cpu"))
    assert math.isclose(np.sqrt(np.mean((pred - y[-48:]) ** 2)), report.best_val_rmse_um, rel_tol=1e-4)
    assert report.best_val_rmse_um < 0.5 * np.std(y[-48:] - y[:-48].mean())
    metrics = report.metrics()
    assert metrics["epochs_run"] == 21.0 and metrics["stopped_early"] == 0.0
    assert {"grad_norm_mean", "grad_norm_max", "clipped_fraction", "best_val_rmse_um"} <= set(metrics)


def test_minibatch_steps_and_loss_options():
    X, y = _data()
    result = train(_mlp, X, y, _config(batch_size=50, epochs=9, loss="mae"))
    assert result.report.steps == 9 * math.ceil(192 / 50)
    assert np.isfinite(result.report.best_val_rmse_um)


def test_without_validation_tail_fitness_is_read_on_training_data():
    X, y = _data()
    report = train(_mlp, X, y, _config(validation_fraction=0.0, epochs=9)).report
    assert sorted(report.val_rmse_um) == [3, 9] and np.isfinite(report.best_val_rmse_um)


def test_same_seed_same_weights_and_callers_rng_untouched():
    X, y = _data()
    torch.manual_seed(123)
    np.random.seed(123)
    first = train(_mlp, X, y, _config(batch_size=40, epochs=6), random_state=7)
    after_torch, after_np = torch.rand(3), np.random.rand(3)
    torch.manual_seed(123)
    np.random.seed(123)
    assert torch.equal(after_torch, torch.rand(3)) and np.array_equal(after_np, np.random.rand(3))
    second = train(_mlp, X, y, _config(batch_size=40, epochs=6), random_state=7)
    other = train(_mlp, X, y, _config(batch_size=40, epochs=6), random_state=8)
    assert all(torch.equal(first.state_dict[k], second.state_dict[k]) for k in first.state_dict)
    assert not all(torch.equal(first.state_dict[k], other.state_dict[k]) for k in first.state_dict)


def test_early_stopping_counts_cycle_ends_without_improvement():
    X, y = _data()
    # A learning rate far below float32 resolution leaves the weights unchanged, so no read point improves.
    report = train(_mlp, X, y, _config(lr_max=1e-20, t_mult=1, epochs=30, patience=2)).report
    assert report.stopped_early and report.epochs_run == 9 and report.best_epoch == 3
    assert sorted(report.val_rmse_um) == [3, 6, 9]


def test_huge_learning_rate_diverges():
    X, y = _data()
    with pytest.raises(DivergedError, match="diverged") as info:
        train(_mlp, X, y, _config(lr_max=1e6, epochs=50))
    assert info.value.report.epochs_run < 50


def test_persistent_gradient_norm_above_threshold_is_divergence():
    X, y = _data()
    with pytest.raises(DivergedError, match="3 consecutive steps") as info:
        train(_mlp, X, y, _config(diverge_grad_norm=1e-12, diverge_steps=3))
    assert info.value.report.steps == 3
    # The same threshold with more patience than steps is not divergence.
    train(_mlp, X, y, _config(epochs=5, diverge_grad_norm=1e-12, diverge_steps=6))


def test_clipping_caps_the_gradients_the_optimizer_applies():
    X, y = _data()
    seen: list[float] = []

    def record(optimizer, args, kwargs):
        grads = [p.grad for group in optimizer.param_groups for p in group["params"] if p.grad is not None]
        seen.append(float(torch.nn.utils.get_total_norm(grads)))

    handle = register_optimizer_step_pre_hook(record)
    try:
        clipped = train(_mlp, X, y, _config(clip_norm=0.05, epochs=9)).report
        applied_clipped, seen[:] = list(seen), []
        free = train(_mlp, X, y, _config(clip_norm=None, epochs=9)).report
        applied_free = list(seen)
    finally:
        handle.remove()
    assert len(applied_clipped) == clipped.steps == 9
    assert max(applied_clipped) <= 0.05 * (1 + 1e-4)
    assert clipped.grad_norm_max > 0.05 and clipped.clipped_fraction > 0
    # Recorded norms are taken before clipping; unclipped training applies them as they are.
    assert max(applied_free) > 0.05 and math.isclose(max(applied_free), free.grad_norm_max, rel_tol=1e-5)
    assert free.clipped_fraction == 0


def test_reports_at_cycle_ends_only_inside_reporting():
    X, y = _data()
    study = optuna.create_study(pruner=optuna.pruners.NopPruner())
    trial = study.ask()
    with reporting(trial):
        report = train(_mlp, X, y, _config(epochs=25)).report  # cycle ends 3, 9, 21; epoch 25 is not one
    train(_mlp, X, y, _config(epochs=25))  # outside the context: must not report
    study.tell(trial, report.best_val_rmse_um)
    assert study.trials[0].intermediate_values == {e: report.val_rmse_um[e] for e in (3, 9, 21)}
    assert 25 in report.val_rmse_um  # the budget end is read for the checkpoint, not reported


def test_pruner_stops_training_at_the_first_cycle_end():
    X, y = _data()
    study = optuna.create_study(pruner=_AlwaysPrune())
    trial = study.ask()
    with reporting(trial), pytest.raises(optuna.TrialPruned, match="epoch 3"):
        train(_mlp, X, y, _config())
    study.tell(trial, state=optuna.trial.TrialState.PRUNED)
    assert list(study.trials[0].intermediate_values) == [3]


def test_trainer_search_space_holds_the_stabilisers():
    space = trainer_search_space()
    assert set(space) == {"trainer__lr_max", "trainer__eta_min_ratio", "trainer__t0", "trainer__t_mult",
                          "trainer__clip_norm"}
    space["trainer__lr_max"]["low"] = 1.0
    assert trainer_search_space()["trainer__lr_max"]["low"] < 1.0
