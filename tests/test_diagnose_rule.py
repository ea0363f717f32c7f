"""The finder's decision rule when the baseline is imperfect: the whitened statistic is calibrated under
autocorrelated misfit, false discoveries are controlled across candidates and rounds, and reports are truthful
(finite intervals that contain the value, unidentifiable parameters held and named, fitted values in headings)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from thermodrift.core import registry
from thermodrift.core.physics.calibration import FreeParameter
from thermodrift.core.physics.diagnose import fitted_label, noise, report, screening, selection

REG = registry.default()


def _ar1(rng, n: int, phi: float) -> np.ndarray:
    e = rng.normal(0.0, 1.0, n)
    x = np.empty(n)
    x[0] = e[0] / np.sqrt(1 - phi ** 2)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


def _screen_p(resid: np.ndarray, response: np.ndarray, whiten: bool) -> float:
    """The screening's p-value of one displacement channel's residual against one candidate response, through
    the finder's own code (its noise model fitted to the residual, or white noise of the residual's spread)."""
    n = len(resid)
    ones = np.ones((n, 1))
    base = screening.Baseline(None, np.zeros((n, 1)), np.zeros((n, 1)), [ones])
    rows, blocks = np.arange(n), np.arange(n) * 8 // n
    sigma = np.array([float(np.std(resid))])
    model = None if whiten else noise.NoiseModel(np.zeros((n, 1)) + rng_white(n))
    screen = screening.prepare(base, resid[:, None], sigma, ["displacement"], ["z"], rows, blocks, noise=model)
    cand = screening.Candidate("ambient_coupling", {}, {}, None, [], response[:, None])
    return screening.score(screen, cand, 1).p_value


def rng_white(n: int) -> np.ndarray:
    """A white series of unit spread: its noise model is the identity (order 0, innovation 1)."""
    return np.random.default_rng(12345).normal(0.0, 1.0, (n, 1))


def test_whitened_statistic_is_calibrated_under_ar1_misfit_with_nothing_missing():
    rng = np.random.default_rng(0)
    n, reps, level = 1200, 300, 0.05
    whitened, white = 0, 0
    for _ in range(reps):
        resid = _ar1(rng, n, 0.95)  # slow, strongly correlated misfit; nothing missing
        response = np.cumsum(rng.normal(0.0, 1.0, n))  # a slow candidate response, unrelated to it
        whitened += _screen_p(resid, response, whiten=True) < level
        white += _screen_p(resid, response, whiten=False) < level
    assert 0.02 <= whitened / reps <= 0.09  # near the stated level
    assert white / reps > 0.4  # the white-noise statistic would reject far too often


def test_whitened_statistic_still_finds_a_real_effect_in_ar1_misfit():
    rng = np.random.default_rng(1)
    n = 1200
    response = np.repeat(rng.choice([0.0, 1.0, 4.0], 12), n // 12)  # centrifugal-like steps
    resid = _ar1(rng, n, 0.95) + 1.5 * response
    assert _screen_p(resid, response, whiten=True) < 1e-6


def test_ar_fit_recovers_the_coefficient_and_whitening_leaves_white_noise():
    rng = np.random.default_rng(2)
    x = _ar1(rng, 5000, 0.8)
    a, s = noise.ar_fit(x)
    assert a[0] == pytest.approx(0.8, abs=0.05) and s == pytest.approx(1.0, abs=0.05)
    e = noise.whiten(x, a)[len(a):]
    assert abs(np.corrcoef(e[1:], e[:-1])[0, 1]) < 0.05


def test_benjamini_hochberg_controls_false_discoveries_and_keeps_true_ones():
    rng = np.random.default_rng(3)
    level, reps, false_any = 0.05, 2000, 0
    for _ in range(reps):
        false_any += any(noise.benjamini_hochberg(rng.uniform(size=30).tolist(), level))
    assert false_any / reps <= level * 1.2  # all null: the false-discovery rate is the family-wise rate
    p = [1e-8, 2e-6, 0.3, 0.7] + rng.uniform(size=20).tolist()
    found = noise.benjamini_hochberg(p, level)
    assert found[:2] == [True, True] and not any(found[2:])


def test_rounds_spend_the_level_and_stay_below_it():
    levels = [noise.round_level(0.01, r) for r in range(20)]
    assert sum(levels) < 0.01 and all(a > b for a, b in zip(levels, levels[1:]))


def _fp(name: str, low: float, high: float, scale: str = "log") -> FreeParameter:
    return FreeParameter(name, (f"sources.x.{name}",), low, low, high, "1", scale=scale)


def _bearing_win(parameters: dict, ci: dict, fixed: dict | None = None,
                 shift_scale: str = "linear") -> selection.Fitted:
    cand = screening.Candidate("bearing_heat_law", {"node": "spindle"}, {"exponent_shift": 0.0,
                               "viscosity_coeff_per_K": 0.01}, None, [], np.zeros((1, 1)),
                               label="bearing_heat_law at node=spindle (exponent_shift=0, viscosity_coeff_per_K=0.01)")
    declared = [(_fp("exponent_shift", -1.0, 1.0, shift_scale), 0.0), (_fp("viscosity_coeff_per_K", 1e-4, 0.1), 0.01)]
    return selection.Fitted(cand, None, None, 10.0, 10.0, 2, 1e-9, dict(parameters), dict(ci), declared=declared,
                            fixed=dict(fixed or {}))


def test_an_interval_that_is_infinite_or_misses_its_value_is_not_trusted():
    fp = _fp("viscosity_coeff_per_K", 1e-4, 0.1)
    assert not selection.trustworthy(1e-4, [0.0, 7.823e256], fp)
    assert not selection.trustworthy(1e-4, None, fp)
    assert not selection.trustworthy(0.02, [0.001, 0.01], fp)  # does not contain the value
    assert not selection.trustworthy(0.01, [0.001, 0.05], fp)  # a factor 50: not identified
    assert selection.trustworthy(0.01, [0.008, 0.012], fp)
    assert selection.trustworthy(-1.0, [-1.14, -0.84], _fp("exponent_shift", -1.0, 1.0, "linear"))


def test_an_unidentifiable_parameter_is_held_left_out_and_named():
    # (the kept parameter solved linearly: no search to redo with the other one held)
    win = _bearing_win({"exponent_shift": -1.0, "viscosity_coeff_per_K": 1e-4},
                       {"exponent_shift": [-1.14, -0.84], "viscosity_coeff_per_K": [0.0, 7.823e256]},
                       shift_scale="projected")
    held = selection.identified(win, None, 1)
    assert "viscosity_coeff_per_K" not in held.parameters and "viscosity_coeff_per_K" not in held.ci
    assert held.fixed == {"viscosity_coeff_per_K": 1e-4}
    for k, v in held.parameters.items():
        lo, hi = held.ci[k]
        assert np.isfinite([lo, hi]).all() and lo <= v <= hi


def test_the_heading_shows_fitted_values_not_start_values():
    win = _bearing_win({"exponent_shift": -1.0}, {"exponent_shift": [-1.14, -0.84]},
                       fixed={"viscosity_coeff_per_K": 1e-4})
    label = fitted_label(win)
    assert "exponent_shift=-1" in label and "viscosity_coeff_per_K=0.0001" in label
    assert "=0.01" not in label and "exponent_shift=0" not in label
    finding = {"mechanism": "bearing_heat_law", "confidence": 0.8, "parameters": {"exponent_shift": -1.0},
               "ci": {"exponent_shift": [-1.14, -0.84]}, "where": [], "evidence": "e.", "test": "whitened LR",
               "statistic": 12.0, "dof": 2, "p_value": 1e-9, "fdr_level": 0.005,
               "fixed": {"viscosity_coeff_per_K": 1e-4}, "label": label, "_windows": []}
    d = SimpleNamespace(findings=[finding], baseline_network=SimpleNamespace(name="auto"), screened=10,
                        time_s=np.arange(10.0) * 3600, fit_rows=np.arange(10) < 8, seconds=1.0, trace=[])
    doc = {"verdict": "v", "baseline": {"rmse_um": {}, "heldout_rmse_um": {}},
           "augmented": {"rmse_um": {}, "heldout_rmse_um": {}}, "rejected": []}
    md = report.markdown(d, doc, "")
    heading = next(line for line in md.splitlines() if line.startswith("### "))
    assert "exponent_shift=-1" in heading and "viscosity_coeff_per_K=0.0001" in heading
    assert "false-discovery level 0.005" in md and "held: not identifiable" in md
