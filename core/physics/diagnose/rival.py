"""The generic structural rival: a mechanism is named only if it explains more than a generic fast path would.

On an ``auto`` baseline (its structure chosen from data, :mod:`.adequacy`) the residual holds structural misfit
that no mechanism explains, and a flexible mechanism can soak it up: the commonest false finding on machines that
are not ours is a speed-driven law (a centrifugal n² step) fitting the fast misfit of the baseline's structure.
Part of that misfit is timing: the network holds each logged input over the step after it (zero-order hold),
while a machine log's value is the mean over the interval before it, so every fast thermal response the network
makes comes one step late, and a part of short time constant (a spindle nose) the surface sensors do not
show is missing altogether. So in every round in which a candidate judged on the drift channels passes the tests,
the finder also fits a generic structural extension of comparable flexibility: one more hidden node of the auto
network's own kind (heated by the spindle as (n/n_ref)^p, one conductance to the ambient: a first-order path of
time constant τ; read by every drift channel through a sensitivity solved linearly beside the baseline's own, as
the auto map does), driven by each logged interval's own input. τ is thermal, a path of minutes
(:data:`TAU_BOUNDS_H`: never the instantaneous step of a centrifugal growth), and p within the auto network's
bounds; both are chosen on a grid (:data:`TAU_GRID`, :data:`EXPONENT_GRID`) by the whitened likelihood-ratio
statistic on the drift channels, on the screening rows and again on the rows before the inner validation block
for its held-out gain. The rival is judged by :func:`.rule.judge` like a candidate; it is never a finding and is
no registered plugin.

Rule (:func:`explains_as_much`): a candidate judged on the drift channels is not identifiable from structural
misfit when the rival's whitened likelihood-ratio statistic on those channels is within :data:`EQUIVALENT` of
the candidate's (the share the finder uses for rival mechanisms) or above, **and** the rival's gain on the inner
validation block, fitted without it, is too: a mechanism must explain the residual clearly better than the rival
on the fitted rows or on data neither saw. A candidate judged on the temperature channels (a sensor's lag) is not
compared: the rival reads nothing but the drift.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

from thermodrift.core.physics.diagnose import rule, screening, selection
from thermodrift.core.physics.diagnose.selection import EQUIVALENT

ID = "structural_rival"
TAU_BOUNDS_H = (5 / 60, 1.0)   # the fast path's time constant (h): minutes, thermal, never instantaneous
TAU_GRID = np.geomspace(*TAU_BOUNDS_H, 9)
EXPONENT_GRID = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)  # speed exponent of its heat, within the auto network's [0.3, 3]
TEXT = "fast path (one more hidden node of the auto network's kind, driven by each logged interval's own speed)"


def fast_path(time_s: np.ndarray, speed_rpm: np.ndarray, n_ref: float, tau_h: float, exponent: float) -> np.ndarray:
    """Temperature rise (K per unit heat at n_ref) of a first-order node of time constant ``tau_h`` (h) heated
    as (n/n_ref)^exponent, the heat of each sample applied over the interval that ends there, from steady state
    at the first sample."""
    u = (np.clip(speed_rpm, 0.0, None) / max(n_ref, 1e-9)) ** exponent
    a = np.exp(-np.diff(time_s, prepend=time_s[0]) / (tau_h * 3600.0))
    y = np.empty_like(u)
    y[0] = u[0]
    for k in range(1, len(u)):  # a recursion with a varying step: no library filter takes per-sample coefficients
        y[k] = a[k] * y[k - 1] + (1.0 - a[k]) * u[k]
    return y


def _with_path(base_readings: np.ndarray, nuisance: list[np.ndarray], measured: np.ndarray, rows: np.ndarray,
               path: np.ndarray, disp: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Readings with every drift channel's linear map solved again on ``rows`` with ``path`` beside its own
    regressors (as :func:`.screening.baseline_of` solves them), and those regressors."""
    readings, regressors = base_readings.copy(), []
    for c, Z in enumerate(nuisance):
        if not disp[c]:
            regressors.append(Z)
            continue
        Z = np.column_stack([Z, path])
        scale = np.maximum(np.abs(Z[rows]).max(axis=0), 1e-12)
        coef = np.linalg.lstsq(Z[rows] / scale, measured[rows, c], rcond=screening.LINEAR_RCOND)[0]
        readings[:, c] = (Z / scale) @ coef
        regressors.append(Z)
    return readings, regressors


def _best(time_s, speed, n_ref, base_readings, nuisance, measured, sigma, rows, noise, disp):
    """(statistic, readings, τ h, exponent) of the grid point with the largest whitened drop on the drift."""
    d0 = selection._squares(((measured - base_readings) / sigma)[rows], noise, nuisance, rows)
    best = None
    for p in EXPONENT_GRID:
        for tau in TAU_GRID:
            readings, regs = _with_path(base_readings, nuisance, measured, rows,
                                        fast_path(time_s, speed, n_ref, tau, p), disp)
            d1 = selection._squares(((measured - readings) / sigma)[rows], noise, regs, rows)
            drop = d0.sum(axis=0) - d1.sum(axis=0)
            if best is None or drop[disp].sum() > best[0][disp].sum():
                best = (drop, readings, float(tau), float(p))
    return best


def fit(screen, base, scenario, measured: np.ndarray, sigma: np.ndarray, weights: np.ndarray, rows: np.ndarray,
        displacement: np.ndarray, validation: selection.Validation) -> tuple[selection.Fitted, dict[str, Any]]:
    """The rival fitted on ``rows`` (and again on the rows before the inner validation block, scored on it) as a
    :class:`.selection.Fitted` that :func:`.rule.judge` takes, and its time constant and exponent."""
    t, speed = scenario.time_s, scenario.frame["speed_rpm"].to_numpy(dtype=float)
    n_ref = base.network.reference_speed_rpm
    drop, readings, tau, p = _best(t, speed, n_ref, base.readings, base.nuisance, measured, sigma, rows,
                                   screen.noise, displacement)
    _, inner, _, _ = _best(t, speed, n_ref, validation.base_readings, base.nuisance, measured, sigma,
                           validation.inner, screen.noise, displacement)
    d0 = (((measured - validation.base_readings) / sigma)[validation.rows]) ** 2
    val_drop = d0.sum(axis=0) - ((((measured - inner) / sigma)[validation.rows]) ** 2).sum(axis=0)
    response = np.zeros_like(measured)
    response[:, displacement] = fast_path(t, speed, n_ref, tau, p)[:, None]
    cand = screening.Candidate(ID, {}, {"tau_h": tau, "exponent": p}, base.network, [], response, TEXT,
                               f"{ID}: {TEXT}, τ {tau * 60:.3g} min, heat ∝ n^{p:g}")
    screening.score(screen, cand, 1)
    dof = 2 + int(displacement.sum())
    dsse = float(drop.sum())
    f = selection.Fitted(cand, base.network, readings, dsse, float(drop @ weights), dof,
                         float(stats.chi2.sf(max(dsse, 0.0), dof)), drop=drop, val_drop=val_drop,
                         val_base=d0.sum(axis=0), val_bal=float(val_drop @ weights),
                         val_disp=float(val_drop[displacement].sum()), val_disp0=float(d0[:, displacement].sum()))
    return f, {"rival": TEXT, "tau_min": round(tau * 60.0, 2), "exponent": p}


def explains_as_much(cand: rule.Judged, rival: rule.Judged) -> bool:
    """True when the rival's judged statistic and its held-out gain are each within :data:`EQUIVALENT` of the
    candidate's or above (module docstring); a candidate judged on the temperature channels is never compared."""
    if cand.group != "drift":
        return False
    return (rival.statistic >= cand.statistic - EQUIVALENT * abs(cand.statistic)
            and rival.val_gain >= cand.val_gain - EQUIVALENT * abs(cand.val_gain))


def describe(shape: dict[str, Any], j: rule.Judged) -> dict[str, Any]:
    """The fitted rival for ``adequacy.structural_rival``: what it is, τ (min), exponent and its statistics on
    the drift channels."""
    return {**shape, "judged_statistic": round(j.statistic, 4), "validation_gain": round(j.val_gain, 4),
            "cv_gain": round(j.cv_gain, 4), "cv_wins": round(j.cv_wins, 3)}


def reason(mechanism: str, rival: dict[str, Any]) -> str:
    """The rejection reason of a candidate the rival explains as much as."""
    return (f"not identifiable from structural misfit: a generic {rival['rival']}, τ {rival['tau_min']:.3g} min, "
            f"heat ∝ n^{rival['exponent']:g}, explains as much (likelihood ratio {rival['judged_statistic']:.3g} "
            f"on the drift channels, held-out gain {rival['validation_gain']:.3g}: within {EQUIVALENT:.0%} of "
            f"{mechanism}'s or above on both)")
