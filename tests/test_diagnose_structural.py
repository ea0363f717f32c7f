"""When the baseline's held-out misfit is structural, only decisive evidence names a mechanism: a candidate that
passes every other test but leaves the misfit structural is withheld ("cannot tell", with the reason); on a
baseline that is right up to noise the same rule names it, and a candidate that accounts for the misfit is
named on either."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from thermodrift.core.physics.diagnose import adequacy, rule

N, BLOCKS = 400, 8
VAL = np.arange(N - N // BLOCKS, N)  # the inner validation block: the last condition block
KINDS = ["temperature", "displacement"]
DISPLACEMENT = np.array([False, True])
GROUP_IS_DRIFT = np.array([False, True])
SIGMA = np.ones(2)
THERMAL = np.column_stack([np.ones(N), np.linspace(0, 2, N)])  # a response that reaches the drift


def _measured(rng) -> np.ndarray:
    """Temperature and drift readings (noise units) of a machine whose drift carries a slow swing."""
    t = np.arange(N)
    return np.column_stack([rng.normal(0, 1, N), 6.0 * np.sin(2 * np.pi * t / 90.0) + rng.normal(0, 1, N)])


def _baseline(measured: np.ndarray, missed: float) -> np.ndarray:
    """A baseline's readings that miss ``missed`` (share) of the slow swing and nothing else but the noise."""
    t = np.arange(N)
    readings = np.zeros_like(measured)
    readings[:, 1] = (1 - missed) * 6.0 * np.sin(2 * np.pi * t / 90.0)
    return readings


def _candidate(measured: np.ndarray, base: np.ndarray, explains: float) -> SimpleNamespace:
    """A fitted candidate that, fitted without the validation block, predicts ``explains`` (share) of the
    baseline's drift error there and passes every other test (discovered, consistent blocks, guarded)."""
    resid = measured - base
    after = resid.copy()
    after[:, 1] = resid[:, 1] - explains * (resid[:, 1] - (measured[:, 1] - _baseline(measured, 0.0)[:, 1]))
    d0, d1 = (resid[VAL] ** 2).sum(axis=0), (after[VAL] ** 2).sum(axis=0)
    cand = SimpleNamespace(response=THERMAL, cv_blocks=np.tile([1.0, 3.0], (BLOCKS, 1)))
    return SimpleNamespace(candidate=cand, readings=measured - after, drop=np.array([5.0, 60.0]), dof=1,
                           outside=[], val_drop=d0 - d1, val_base=d0)


def _decide(measured: np.ndarray, base: np.ndarray, f) -> tuple[bool, dict, rule.Judged]:
    misfit = adequacy.heldout_misfit(KINDS, SIGMA, measured, VAL, base)
    j = rule.judge(f, DISPLACEMENT, GROUP_IS_DRIFT, measured, SIGMA, np.arange(N), np.arange(N) * BLOCKS // N, VAL)
    return rule.passes(f, j, True, 0.0, misfit["structural"]), misfit, j


def test_a_proxy_on_a_structurally_wrong_baseline_is_withheld_and_the_same_evidence_names_on_a_right_one():
    rng = np.random.default_rng(0)
    measured = _measured(rng)
    wrong = _baseline(measured, 1.0)  # misses the whole swing: held-out RMS ≈ 4.4 σ
    proxy = _candidate(measured, wrong, 0.4)  # shaves 40 % of it: leaves ≈ 2.7 σ
    named, misfit, j = _decide(measured, wrong, proxy)
    assert misfit["structural"] and misfit["rms_over_noise"] > 3.5
    assert rule.passes(proxy, j, True)  # every other test holds: only the structural bar withholds it
    assert not named and j.left_rms() > adequacy.HELD_OUT_RATIO
    reason = rule.why_not(proxy, j, True, 0.005, 10, misfit["rms_over_noise"])
    assert reason.startswith("cannot tell: the baseline's misfit is structural")
    # a baseline right up to noise: the held-out misfit is noise and a candidate with a held-out gain is named
    right = _baseline(measured, 0.0)
    small = _candidate(measured, right, 0.0)
    small.val_drop = small.val_drop + np.array([0.0, 1.0 * len(VAL)])  # one noise variance per sample better
    named, misfit, j = _decide(measured, right, small)
    assert not misfit["structural"] and 0.7 < misfit["rms_over_noise"] < 1.3
    assert named


def test_a_mechanism_that_accounts_for_a_structural_misfit_is_still_named():
    rng = np.random.default_rng(1)
    measured = _measured(rng)
    wrong = _baseline(measured, 1.0)
    truth = _candidate(measured, wrong, 1.0)  # explains the swing: leaves the noise
    named, misfit, j = _decide(measured, wrong, truth)
    assert misfit["structural"] and named and j.left_rms() < 1.3


def test_a_candidate_that_shaves_a_marginal_structural_misfit_is_withheld():
    rng = np.random.default_rng(2)
    measured = _measured(rng)
    wrong = _baseline(measured, 0.5)  # misses half the swing: held-out RMS just over 2 σ
    shave = _candidate(measured, wrong, 0.15)  # leaves under 2 σ but removes under half the excess over noise
    named, misfit, j = _decide(measured, wrong, shave)
    assert misfit["structural"] and misfit["rms_over_noise"] < 3.0
    assert j.left_rms() <= adequacy.HELD_OUT_RATIO and rule.passes(shave, j, True)
    assert not named
