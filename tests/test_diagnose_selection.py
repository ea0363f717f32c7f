"""The finder's choice rules: the most parsimonious of indistinguishable candidates is named, a fit is never kept
worse than its start by the finder's own statistic, start amplitudes come from the screening (and, for the inner
validation fit, from the blocks before the validation block alone)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from thermodrift.core import physics, registry
from thermodrift.core.physics.diagnose import diagnose, screening, selection
from thermodrift.core.physics.diagnose.concealed import concealed_case

REG = registry.default()


def _fitted(mechanism: str, block_bal: np.ndarray, dof: int = 1) -> selection.Fitted:
    """A fitted candidate whose per-block raw and balanced gains are ``block_bal``."""
    cand = SimpleNamespace(mechanism=mechanism, factory=REG.get("mechanism", mechanism).factory)
    total = float(block_bal.sum())
    return selection.Fitted(cand, None, None, total, total, dof, 0.0, block_raw=block_bal.copy(),
                            block_bal=block_bal.copy())


def test_of_indistinguishable_candidates_the_one_with_fewer_nonlinear_laws_is_named():
    rng = np.random.default_rng(0)
    gain = 1000.0 + rng.normal(0, 5, 8)
    # radiation fits a hair better (a rounding step of its search); convection assumes no T⁴ law
    radiation, convection = _fitted("radiation", gain + 1e-3), _fitted("ambient_coupling", gain)
    assert REG.get("mechanism", "radiation").factory.laws and not REG.get("mechanism", "ambient_coupling").factory.laws
    assert selection.parsimonious([radiation, convection], alpha=0.01) is convection
    # a real, consistent advantage of the nonlinear law over every block is kept, though within 5 %
    better = _fitted("radiation", gain + 30.0 + rng.normal(0, 1, 8))
    assert selection.parsimonious([better, convection], alpha=0.01) is better
    # fewer free parameters come before fewer laws
    two = _fitted("ambient_coupling", gain + 1e-3, dof=2)
    assert selection.parsimonious([two, radiation], alpha=0.01) is radiation


def test_bootstrap_confidence_follows_the_same_choice():
    rng = np.random.default_rng(1)
    gain = 1000.0 + rng.normal(0, 5, 8)
    fitted = [_fitted("radiation", gain + 1e-3), _fitted("ambient_coupling", gain)]
    inclusion = selection.bootstrap_inclusion(fitted, 8, 10, 0.01, 50, 0)
    assert inclusion == {"ambient_coupling": 1.0}


def test_amplitudes_for_the_validation_fit_come_from_the_kept_blocks_alone():
    stats_ = np.abs(np.random.default_rng(2).normal(1, 0.5, (5, 2, 3)))
    screen = SimpleNamespace(group_names=["temperatures", "z"], temps_first=True)
    cand = screening.Candidate("cutting_heat", {}, {}, None, [], np.zeros((1, 2)), block_stats=stats_)
    keep = np.array([True, True, False, True, False])
    out = screening.restricted(screen, cand, keep)
    tot = stats_[keep].sum(axis=0)
    assert out.beta == pytest.approx({n: tot[g, 0] / tot[g, 1] for g, n in enumerate(screen.group_names)})
    stats_[~keep] *= 7.0  # what the validation blocks hold does not move the start
    assert screening.restricted(screen, cand, keep).beta == pytest.approx(out.beta)


def test_a_held_amplitude_of_a_shaped_mechanism_starts_at_the_screening_amplitude():
    cls = REG.get("mechanism", "slow_structural_mode").factory
    part = SimpleNamespace(factory=cls, shape={"tau_h": 6.0})
    net = physics.load_network("vmc_spindle_s2")
    _, free = cls(**cls.places(net)[0]).declare(net, tau_h=6.0)
    held = selection._held_amplitudes(part, free, 0.5)
    default = {p.name: p.default for p in cls.parameters}
    assert held == {"G_W_K": pytest.approx(0.5 * default["G_W_K"])}  # τ is the shape, the gain is searched
    assert selection._held_amplitudes(part, free, 0.0) == {}


def test_a_preload_feedback_the_calibration_search_overshoots_is_still_found():
    """The search's own weighting moves the gain to where the finder's statistic is worse than at the
    screening's start; the start is kept and the feedback found (drawn like a benchmark case)."""
    case = concealed_case(physics.load_network("motorized_spindle_s3"), "preload_feedback", 1016, dt_s=120.0)
    d = diagnose(case.recording, case.baseline, seed=0, bootstrap=50,
                 only=["preload_feedback", "bearing_heat_law", "contact_resistance"])
    assert d.findings and d.findings[0]["mechanism"] == "preload_feedback"
    fit = next(t for t in d.trace if t["candidate"].startswith("preload_feedback"))
    assert fit["fit_share"] >= 0.9 * fit["screen_share"]


def test_a_constant_offset_of_the_ambient_input_is_absorbed_by_the_baseline(monkeypatch):
    """A boundary sensor's unknown offset (Pt100 tolerance) is a linear nuisance of the baseline, not a residual
    a mechanism could score on: the network's temperature-dependent heat makes it more than a per-channel offset."""
    from thermodrift.core.physics.scenarios import Scenario

    case = concealed_case(physics.load_network("demo_spindle"), None, 4, hours=14.0, dt_s=120.0)
    rec, net = case.recording, case.baseline
    channels = [s.name for s in net.sensors]
    measured = rec.data[channels].to_numpy(dtype=float)
    rows = np.arange(len(rec))
    sigma = np.array([s.noise_K if hasattr(s, "noise_K") else s.noise_um for s in net.sensors])
    scenario = Scenario.from_recording(rec)
    frame = scenario.frame.copy()
    frame["ambient_degC"] += 0.3
    offset = Scenario(frame, scenario.name)

    def misfit(sc):
        r = measured - screening.baseline_of(net, sc, channels, measured, rows, sigma).readings
        return float((r ** 2).sum())

    plain, shifted = misfit(scenario), misfit(offset)
    assert shifted == pytest.approx(plain, rel=0.01)
    monkeypatch.setattr(screening, "BOUNDARY_INPUTS", ())
    assert misfit(offset) > 1.05 * misfit(scenario)
