"""The acceptance rule judges a candidate on the channels it reaches: the drift when its response reaches the
drift channels (temperatures only guard), the temperatures for a change of readings alone (a sensor's lag);
its held-out gain must exceed the block-to-block spread of the error it leaves on those channels."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from thermodrift.core.physics.diagnose import rule

N, BLOCKS = 400, 8
TEMP, DRIFT = 0, 1  # channel 0: a temperature (°C), channel 1: a drift (µm)
DISPLACEMENT = np.array([False, True])
GROUP_IS_DRIFT = np.array([False, True])  # amplitude groups: temperatures, then the drift channel


def _fitted(response: np.ndarray, readings: np.ndarray, val_drop=(0.0, 50.0), drop=(5.0, 60.0),
            cv_blocks: np.ndarray | None = None) -> SimpleNamespace:
    cv = np.tile([1.0, 3.0], (BLOCKS, 1)) if cv_blocks is None else cv_blocks
    cand = SimpleNamespace(response=response, cv_blocks=cv)
    return SimpleNamespace(candidate=cand, readings=readings, drop=np.array(drop), dof=1, outside=[],
                           val_drop=np.array(val_drop, dtype=float), val_base=np.array([400.0, 100.0]))


def _case(rng, drift_spread: float):
    """Measured and a model's readings on the screening rows: the drift error's size varies from block to
    block by ``drift_spread`` (noise units)."""
    blocks = np.arange(N) * BLOCKS // N
    scale = 1.0 + drift_spread * rng.uniform(0, 1, BLOCKS)[blocks]
    measured = np.column_stack([rng.normal(0, 1, N), rng.normal(0, 1, N) * scale])
    return measured, np.ones(2), np.arange(N), blocks, np.arange(N - N // BLOCKS, N)


READINGS = np.zeros((N, 2))


def test_a_response_that_reaches_the_drift_is_judged_on_it_and_a_lag_on_the_temperatures():
    rng = np.random.default_rng(0)
    measured, sigma, rows, blocks, val = _case(rng, 0.5)
    readings = READINGS
    thermal = np.column_stack([np.ones(N), np.linspace(0, 2, N)])
    lag = np.column_stack([np.ones(N), np.zeros(N)])
    jt = rule.judge(_fitted(thermal, readings), DISPLACEMENT, GROUP_IS_DRIFT, measured, sigma, rows, blocks, val)
    jl = rule.judge(_fitted(lag, readings, val_drop=(40.0, 0.0)), DISPLACEMENT, GROUP_IS_DRIFT, measured, sigma,
                    rows, blocks, val)
    assert (jt.group, jt.statistic, jt.val_gain, jt.guard_gain) == ("drift", 60.0, 50.0, 0.0)
    assert jt.cv_gain == 3.0 * BLOCKS and jt.cv_wins == 1.0
    assert (jl.group, jl.statistic, jl.val_gain) == ("temperatures", 5.0, 40.0)
    assert jl.cv_gain == 1.0 * BLOCKS


def test_a_held_out_gain_within_the_block_spread_is_structural_misfit_not_a_finding():
    rng = np.random.default_rng(1)
    thermal = np.column_stack([np.ones(N), np.linspace(0, 2, N)])
    calm = _case(rng, 0.0)
    rough = _case(rng, 40.0)  # the error it leaves varies a lot from block to block
    f = _fitted(thermal, READINGS, val_drop=(0.0, 1.0 * N / BLOCKS))  # a noise variance per sample better
    j_calm = rule.judge(f, DISPLACEMENT, GROUP_IS_DRIFT, *calm)
    j_rough = rule.judge(f, DISPLACEMENT, GROUP_IS_DRIFT, *rough)
    assert j_rough.spread > 10 * j_calm.spread
    assert rule.passes(f, j_calm, True)
    assert not rule.passes(f, j_rough, True)
    assert "structural misfit" in rule.why_not(f, j_rough, True, 0.005, 10)
    assert not rule.passes(f, j_calm, False)  # not a discovery


def test_a_drift_gain_bought_by_much_worse_temperatures_is_refused():
    rng = np.random.default_rng(2)
    measured, sigma, rows, blocks, val = _case(rng, 0.0)
    readings = READINGS
    thermal = np.column_stack([np.ones(N), np.linspace(0, 2, N)])
    good = _fitted(thermal, readings, val_drop=(-0.05 * 400.0, 30.0))
    bad = _fitted(thermal, readings, val_drop=(-20 * 400.0, 30.0))
    case = (DISPLACEMENT, GROUP_IS_DRIFT, measured, sigma, rows, blocks, val)
    assert rule.passes(good, rule.judge(good, *case), True)
    j = rule.judge(bad, *case)
    assert not rule.passes(bad, j, True) and "other channels worse" in rule.why_not(bad, j, True, 0.005, 10)


def test_blocks_that_do_not_improve_on_the_judged_channels_refuse_it():
    rng = np.random.default_rng(3)
    measured, sigma, rows, blocks, val = _case(rng, 0.0)
    readings = READINGS
    thermal = np.column_stack([np.ones(N), np.linspace(0, 2, N)])
    cv = np.tile([5.0, -1.0], (BLOCKS, 1))  # the temperatures improve in every block, the drift in none
    f = _fitted(thermal, readings, cv_blocks=cv)
    j = rule.judge(f, DISPLACEMENT, GROUP_IS_DRIFT, measured, sigma, rows, blocks, val)
    assert j.cv_wins == 0.0 and not rule.passes(f, j, True)


def test_a_gain_carried_by_one_block_is_not_consistent_over_the_conditions():
    rng = np.random.default_rng(4)
    measured, sigma, rows, blocks, val = _case(rng, 0.0)
    thermal = np.column_stack([np.ones(N), np.linspace(0, 2, N)])
    spiky = np.zeros((BLOCKS, 2))
    spiky[:, 1] = [40.0, 0.5, 0.4, 0.6, -0.5, 0.3, -0.4, -0.6]  # most of the gain in one block
    steady = np.zeros((BLOCKS, 2))
    steady[:, 1] = [3.0, 2.5, 3.5, 2.0, 4.0, 3.0, 2.8, 3.2]
    case = (DISPLACEMENT, GROUP_IS_DRIFT, measured, sigma, rows, blocks, val)
    f_spiky, f_steady = _fitted(thermal, READINGS, cv_blocks=spiky), _fitted(thermal, READINGS, cv_blocks=steady)
    j_spiky, j_steady = rule.judge(f_spiky, *case), rule.judge(f_steady, *case)
    assert j_spiky.cv_gain > j_steady.cv_gain and j_spiky.cv_wins >= 0.5
    assert not j_spiky.consistent() and j_steady.consistent()
    assert rule.passes(f_steady, j_steady, True) and not rule.passes(f_spiky, j_spiky, True)
    assert "consistently" in rule.why_not(f_spiky, j_spiky, True, 0.005, 10)


def test_a_decisive_held_out_gain_stands_in_for_the_test_never_for_the_blocks():
    rng = np.random.default_rng(5)
    measured, sigma, rows, blocks, val = _case(rng, 0.0)
    thermal = np.column_stack([np.ones(N), np.linspace(0, 2, N)])
    case = (DISPLACEMENT, GROUP_IS_DRIFT, measured, sigma, rows, blocks, val)
    spiky = np.zeros((BLOCKS, 2))
    spiky[:, 1] = [40.0, 0.5, 0.4, 0.6, -0.5, 0.3, -0.4, -0.6]  # blocks not consistent
    strong = dict(val_drop=(0.0, 90.0))  # 1.8 noise variances per sample better on a block missed by 2 per sample
    f_ok, f_spiky = _fitted(thermal, READINGS, **strong), _fitted(thermal, READINGS, cv_blocks=spiky, **strong)
    j_ok, j_spiky = rule.judge(f_ok, *case), rule.judge(f_spiky, *case)
    assert j_ok.held_out_p() < 1e-4 and j_ok.held_out_t() == pytest.approx(1.8 / j_ok.spread)
    assert j_ok.three_lines(True) and not j_ok.three_lines(False)
    assert rule.passes(f_ok, j_ok, False, decisive_level=1e-3)        # the test missed, the blocks hold
    assert not rule.passes(f_spiky, j_spiky, True, decisive_level=1e-3)   # the blocks missed
    assert not rule.passes(f_ok, j_ok, False)  # no decisive level: the three lines of evidence are needed

