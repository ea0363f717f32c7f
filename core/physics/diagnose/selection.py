"""Fitting the most promising candidates by re-simulation and choosing forward.

A candidate's augmented network is calibrated with only the mechanism's own free parameters searched
(``log`` ones in log space, ``linear`` ones directly, ``projected`` ones solved linearly with the
baseline's sensitivities and offsets) on the screening rows; the baseline's parameters stay at their
calibrated values. Its score is the drop of the noise-weighted residual sum of squares over those rows: with
known noise σ that is the likelihood-ratio statistic, χ²(free parameters) when nothing is missing, tested at a
Bonferroni level α/m over the m screened candidates.

The calibration search minimises its own objective (each channel weighted by the larger of its noise and
its misfit at the start), not this statistic, and on some recordings ends where the statistic is worse than
at the start it was given (the screening's linearised amplitude). The start, with only the linear parameters
solved, is therefore scored too and the better of the two is kept, by the whitened statistic on the channels
the candidate is judged on (:mod:`.rule`: the drift channels when its response reaches them), else balanced (the
search result's intervals go with it; the start has none). A shaped mechanism (it declares ``shapes``) with amplitude
parameters its search leaves fixed (the slow mode's conductance) is fitted from two starts, those at their
default and at the screening's temperature amplitude, and the better is kept alike.

Of the passing candidates that explain the residual within :data:`EQUIVALENT` of the best one and that the
data cannot tell apart from it (:func:`indistinguishable`), the most parsimonious is named: the fewest free
parameters, then the fewest nonlinear constitutive laws (``Mechanism.laws``); the others are reported as not
identifiable from this data, with the experiment that separates them.

The same candidate is also fitted by re-simulation on the screening rows before an inner validation block
(their last condition run or runs, cut like the final block) and scored on that block against the baseline
refitted on the same rows: a mechanism must predict data its fit did not see, the way the final block and
the controller will use it, not only lower the misfit where it was fitted. Its start amplitudes are read
from the screening blocks before that block only.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from thermodrift.core.physics.calibration import UNIDENTIFIABLE_RATIO, FreeParameter, calibrate
from thermodrift.core.physics.diagnose import rule
from thermodrift.core.physics.diagnose.noise import NoiseModel
from thermodrift.core.physics.diagnose.screening import (Candidate, Screen, _basis_of, _place_text, baseline_of,
                                                        restricted)
from thermodrift.core.physics.network import Network

EQUIVALENT = 0.05   # rival within this share of the winner's balanced gain: a candidate for "not identifiable"

@dataclass
class Fitted:
    candidate: Candidate
    network: Network
    readings: np.ndarray
    dsse: float           # drop of the noise-weighted residual sum of squares (the known-noise LR statistic)
    dsse_bal: float       # the same with temperature and displacement channels balanced
    dof: int
    p_value: float
    parameters: dict[str, float] = field(default_factory=dict)
    ci: dict[str, Any] = field(default_factory=dict)
    outside: list[str] = field(default_factory=list)  # parameters fitted outside their physical bounds
    block_raw: Any = None  # per condition block: drop of the noise-weighted sum of squares
    block_bal: Any = None  # the same, balanced
    val_bal: float = float("nan")  # balanced drop on the inner validation block, fitted without it
    val_disp: float = float("nan")  # the same over the displacement channels alone
    val_disp0: float = float("nan")  # the baseline's noise-weighted sum of squares there, displacement channels
    val_disp_n: int = 0              # the number of displacement values it sums
    declared: list = field(default_factory=list)  # (FreeParameter, start) of every parameter the mechanism declares
    fixed: dict[str, float] = field(default_factory=dict)  # parameters the data cannot identify, held at a value
    spread: float = 0.0  # standard error of its held-out block error (noise units per sample), set by the finder
    drop: Any = None       # per channel: drop of the whitened sum of squares on the fitted rows
    block_drop: Any = None  # (blocks, channels): the same per condition block
    val_drop: Any = None   # per channel: drop of the noise-weighted sum of squares on the inner validation block
    val_base: Any = None   # per channel: the baseline's noise-weighted sum of squares there


def _declared(cand: Candidate, base: Network,
              scale_held: bool = False) -> tuple[Network, list[tuple[FreeParameter, float]]] | None:
    """The augmented network at start values and each free parameter with its start value.

    The screening's temperature amplitude rescales the first log parameter of a pure-amplitude mechanism; with
    ``scale_held``, those of a shaped one (it declares ``shapes``) that its search leaves fixed
    (:func:`_held_amplitudes`; None when it has none).
    """
    parts = cand.parts or [cand]
    amps = cand.part_betas if cand.parts else [cand.beta.get("temperatures", 0.0)]
    net, out, scaled = base, [], False
    for part, amp in zip(parts, amps):
        before = net
        mech = part.factory(**part.options)
        net, free = mech.declare(before, **part.shape)
        held = _held_amplitudes(part, free, amp) if scale_held and getattr(cand.factory, "shapes", ()) else {}
        if held:
            net, free = mech.declare(before, **part.shape, **held)
            scaled = True
        if len(parts) > 1:
            free = [dataclasses.replace(fp, name=f"{fp.name}@{_place_text(part.options)}") for fp in free]
        logs = [fp for fp in free if fp.scale == "log"]
        for fp in free:
            start = fp.value
            if logs and fp is logs[0] and not getattr(cand.factory, "shapes", ()) and amp > 0:
                start = float(np.clip(fp.value * amp, fp.low, fp.high))
            out.append((fp, start))
    return None if scale_held and not scaled else (net, out)


def _held_amplitudes(part: Candidate, free: list[FreeParameter], amp: float) -> dict[str, float]:
    """Amplitude parameters (neutral 0) of a shaped candidate that the fit does not search, at their default ×
    the screening's temperature amplitude ``amp``: a heat path held at its default would keep the default's
    temperature response, however much the screening scaled it (within the parameter's bounds; none when
    ``amp`` ≤ 0)."""
    if amp <= 0:
        return {}
    searched = {fp.name.split("[")[0] for fp in free} | set(part.shape)
    return {p.name: float(np.clip(p.default * amp, p.low, p.high)) for p in part.factory.parameters
            if p.neutral == 0.0 and p.default != 0.0 and p.name not in searched}


@dataclass
class Validation:
    """The inner validation split of the screening rows: fit on ``recording`` (rows ``inner``), score on
    ``rows``; ``base_readings`` is the baseline refitted linearly on ``inner``; ``keep`` marks the screening
    blocks wholly before ``rows`` (bool per block of ``screen``), the ones a start amplitude may be read from."""

    recording: Any
    inner: np.ndarray
    rows: np.ndarray
    base_readings: np.ndarray
    screen: Screen
    keep: np.ndarray


def fit(cand: Candidate, base: Network, fit_recording, scenario, channels: list[str], measured: np.ndarray,
        sigma: np.ndarray, weights: np.ndarray, base_readings: np.ndarray, rows: np.ndarray, blocks: np.ndarray,
        max_evaluations: int, level: float = 0.95, validation: Validation | None = None,
        displacement: np.ndarray | None = None, noise: NoiseModel | None = None) -> Fitted:
    """Calibrate the candidate's free parameters by re-simulation and score the augmented network.

    ``weights`` per channel balance the channel kinds for ``dsse_bal``; ``displacement`` marks the
    displacement channels (bool per channel) for ``val_disp``; ``noise`` whitens the residuals of the fitted
    rows before their sums of squares are compared (:mod:`.noise`; None: white, in units of ``sigma``).
    """
    # the fit kept is the better one on the channels it is judged on (:mod:`.rule`)
    judged = None if displacement is None else rule.judged_channels(cand.response, displacement)
    fitted = _fit(cand, base, fit_recording, scenario, channels, measured, sigma, weights, base_readings, rows,
                  blocks, max_evaluations, level, intervals=True, noise=noise, judged=judged)
    if validation is not None:
        inner = _fit(restricted(validation.screen, cand, validation.keep), base, validation.recording, scenario,
                     channels, measured, sigma, weights, validation.base_readings, validation.inner, None,
                     max_evaluations, level, intervals=False, noise=noise, judged=judged)
        d0 = (((measured - validation.base_readings) / sigma)[validation.rows]) ** 2
        d1 = (((measured - inner.readings) / sigma)[validation.rows]) ** 2
        drop = d0.sum(axis=0) - d1.sum(axis=0)
        fitted.val_bal = float(drop @ weights)
        fitted.val_drop, fitted.val_base = drop, d0.sum(axis=0)
        if displacement is not None:
            fitted.val_disp, fitted.val_disp0 = float(drop[displacement].sum()), float(d0[:, displacement].sum())
            fitted.val_disp_n = int(d0[:, displacement].size)
    return fitted


def _free_parameters(searched: list[tuple[FreeParameter, float]]) -> list[FreeParameter]:
    """The calibration's free parameters (network units, within the physical bounds) of mechanism parameters
    at the given values."""
    return [fp.on_network_scale(v) for fp, v in searched]


def _squares(resid: np.ndarray, noise: NoiseModel | None, nuisance: list[np.ndarray] | None = None,
             rows: np.ndarray | None = None) -> np.ndarray:
    """Squared residuals (rows, channels) in noise units, whitened per channel by ``noise``; with the
    ``nuisance`` regressors of the model (per channel, all samples) their whitened span is projected out, so
    that the linear parameters count as fitted by generalised least squares under that noise model, as in the
    screening (the readings solve them by ordinary least squares, which can leave steps the whitening
    magnifies)."""
    if noise is None:
        return resid ** 2
    out = []
    for c in range(resid.shape[1]):
        w = noise.apply(c, resid[:, c])
        if nuisance is not None:
            Q = _basis_of(noise.apply(c, nuisance[c][rows]))
            w = w - Q @ (Q.T @ w)
        out.append(w)
    return np.column_stack(out) ** 2


def _fit(cand, base, fit_recording, scenario, channels, measured, sigma, weights, base_readings, rows, blocks,
         max_evaluations, level, intervals: bool, noise: NoiseModel | None = None,
         judged: np.ndarray | None = None) -> Fitted:
    base_nuisance = baseline_of(base, scenario, channels, measured, rows, sigma).nuisance if noise else None
    d0 = _squares(((measured - base_readings) / sigma)[rows], noise, base_nuisance, rows)
    best = None
    for start in (_declared(cand, base), _declared(cand, base, scale_held=True)):
        if start is None:
            continue
        net, declared = start
        searched = [(fp, v) for fp, v in declared if fp.scale in ("log", "linear")]
        net = net.with_values({p: fp.network_value(v) for fp, v in searched for p in fp.paths})
        free = _free_parameters(searched)
        for search in ([True, False] if free else [False]):  # the search result, then its start (see above)
            res = calibrate(fit_recording, net, free=free if search else [], intervals=search and intervals,
                            level=level, max_evaluations=max_evaluations)
            refit = baseline_of(res.network, scenario, channels, measured, rows, sigma)
            readings = refit.readings
            d1 = _squares(((measured - readings) / sigma)[rows], noise, refit.nuisance, rows)
            drop = d0.sum(axis=0) - d1.sum(axis=0)
            dsse_bal = float(drop @ weights)
            key = dsse_bal if judged is None else float(drop[judged].sum())
            if best is None or key > best[5]:
                best = (res, readings, d1, dsse_bal, declared, key)
    res, readings, d1, dsse_bal, declared, _ = best
    dsse = float(d0.sum() - d1.sum())
    dof = max(len(declared), 1)
    values = res.network.parameters()
    params, ci = _values_and_intervals(res, declared)
    slack = 1e-6
    outside = [f"{fp.name} = {params[fp.name]:.4g} {fp.unit} outside [{fp.low:g}, {fp.high:g}]" for fp, _ in declared
               if not fp.low - slack * abs(fp.low) <= params[fp.name] <= fp.high + slack * abs(fp.high)]
    block_raw = block_bal = block_drop = None
    diff = d0 - d1
    if blocks is not None:
        nb = int(blocks.max()) + 1
        block_raw = np.bincount(blocks, diff.sum(axis=1), minlength=nb)
        block_bal = np.bincount(blocks, diff @ weights, minlength=nb)
        block_drop = np.column_stack([np.bincount(blocks, diff[:, c], minlength=nb) for c in range(diff.shape[1])])
    return Fitted(cand, res.network, readings, dsse, dsse_bal, dof,
                  float(stats.chi2.sf(max(dsse, 0.0), dof)), params, ci, outside, block_raw, block_bal,
                  declared=declared, drop=diff.sum(axis=0), block_drop=block_drop)


def _values_and_intervals(res, declared) -> tuple[dict[str, float], dict[str, list[float] | None]]:
    """Each declared parameter's value in the calibrated network and its interval (None where the calibration
    gave none): searched ones from the calibration's estimates, projected ones from its linear intervals."""
    values = res.network.parameters()
    est = {e.name: e for e in res.estimates}
    params, ci = {}, {}
    for fp, _ in declared:
        params[fp.name] = float(fp.from_network(values[fp.paths[0]]))
        e = est.get(fp.name)
        ends = None
        if e is not None and math.isfinite(e.low) and math.isfinite(e.high):
            ends = (e.low, e.high)
        elif fp.scale == "projected" and len(fp.paths) == 1:
            ends = _linear_interval(res, fp.paths[0])
        if ends is not None:
            lo, hi = sorted((fp.from_network(ends[0]), fp.from_network(ends[1])))
            ci[fp.name] = [float(lo), float(hi)]
        else:
            ci[fp.name] = None
    return params, ci


def _linear_interval(res, path: str) -> tuple[float, float] | None:
    """The calibration's interval of a linear output parameter (``outputs.<out>.centrifugal_um`` or
    ``outputs.<out>.sensitivity_um_K.<node>``), None where it has none."""
    parts = path.split(".")
    if parts[0] != "outputs" or len(parts) < 3:
        return None
    key = "centrifugal" if parts[2] == "centrifugal_um" else parts[-1]
    for s in res.network.sensors:
        if getattr(s, "output", None) == parts[1]:
            got = res.linear_ci.get(s.name, {}).get(key)
            if got and got[0] is not None and got[1] is not None:
                return float(got[0]), float(got[1])
    return None


def trustworthy(value: float, interval: list[float] | None, fp: FreeParameter) -> bool:
    """True when ``interval`` is finite, contains ``value`` and is narrower than the parameter's physical range
    (for a log parameter: its high/low ratio below the calibration's ``UNIDENTIFIABLE_RATIO``)."""
    if interval is None or not all(map(math.isfinite, interval)):
        return False
    lo, hi = interval
    slack = 1e-9 * max(abs(value), 1e-300)
    if not lo - slack <= value <= hi + slack or hi - lo >= abs(fp.high - fp.low):
        return False
    return fp.scale != "log" or (lo > 0 and hi / lo < UNIDENTIFIABLE_RATIO)


def _intervals(network: Network, fit_recording, searched: list[tuple[FreeParameter, float]],
               level: float) -> dict[str, list[float] | None]:
    """Intervals of the ``searched`` parameters at their values in ``network`` (the others held), from the
    calibration's Jacobian there (one evaluation, no search)."""
    res = calibrate(fit_recording, network, free=_free_parameters(searched), intervals=True, level=level,
                    max_evaluations=1)
    return _values_and_intervals(res, searched)[1]


def identified(win: Fitted, fit_recording, max_evaluations: int, level: float = 0.95) -> Fitted:
    """``win`` with the parameters the data cannot identify (:func:`trustworthy` fails) fixed at their fitted
    value and left out of ``parameters`` and ``ci`` (named in ``fixed``); the intervals of the others are
    recomputed with those held (the network, its readings and the statistics stay as fitted)."""
    by_name = {fp.name: fp for fp, _ in win.declared}
    params, ci = dict(win.parameters), dict(win.ci)
    searched = [(fp, params[fp.name]) for fp, _ in win.declared if fp.scale in ("log", "linear")]
    if any(ci.get(fp.name) is None for fp, _ in searched):  # kept from its start, the fit has no intervals yet
        ci.update(_intervals(win.network, fit_recording, searched, level))
    bad = {k for k, v in params.items() if not trustworthy(v, ci.get(k), by_name[k])}
    if not bad:
        return dataclasses.replace(win, ci=ci)
    keep = [(fp, v) for fp, v in searched if fp.name not in bad]
    if keep:
        ci.update(_intervals(win.network, fit_recording, keep, level))
    for _ in range(2):  # a parameter whose interval is still untrustworthy with the others held joins them
        bad |= {k for k in params if k not in bad and not trustworthy(params[k], ci.get(k), by_name[k])}
    return dataclasses.replace(win, parameters={k: v for k, v in params.items() if k not in bad},
                               ci={k: v for k, v in ci.items() if k not in bad},
                               fixed={k: params[k] for k in sorted(bad)})


def indistinguishable(raw: np.ndarray, bal: np.ndarray, alpha: float) -> bool:
    """True unless a candidate explains the residual better than another beyond chance, given the per-block
    differences of their gains (``raw``: noise-weighted, ``bal``: balanced): by more than the critical
    likelihood ratio of one parameter at level ``alpha``, and consistently over the condition blocks (one-sided
    paired t-test of the balanced differences at ``alpha``)."""
    if float(raw.sum()) <= stats.chi2.isf(alpha, 1):
        return True
    if len(bal) < 2:
        return False
    se = float(np.std(bal, ddof=1)) / math.sqrt(len(bal))
    return not float(np.mean(bal)) > stats.t.isf(alpha, len(bal) - 1) * se


def _simplest(fitted: list[Fitted], gain: np.ndarray, raw: np.ndarray, bal: np.ndarray, best: int,
              eligible: list[int], alpha: float) -> int:
    """Index of the simplest eligible candidate tied with ``best``: within :data:`EQUIVALENT` of its balanced
    ``gain`` and not beaten by it beyond chance (``raw``, ``bal``: per-block gains, one row per candidate);
    fewest free parameters, then fewest nonlinear laws, then the largest gain."""
    tied = [i for i in eligible if i == best or (
        fitted[i].candidate.mechanism != fitted[best].candidate.mechanism
        and gain[i] >= (1 - EQUIVALENT) * gain[best] and indistinguishable(raw[best] - raw[i], bal[best] - bal[i],
                                                                           alpha))]
    return min(tied, key=lambda i: (fitted[i].dof, len(fitted[i].candidate.factory.laws), -gain[i]))


def parsimonious(passing: list[Fitted], alpha: float) -> Fitted:
    """The candidate to name among ``passing``: the simplest of those the data cannot tell apart from the one
    with the largest balanced gain (:func:`_simplest`)."""
    gain = np.array([f.dsse_bal for f in passing])
    raw, bal = np.stack([f.block_raw for f in passing]), np.stack([f.block_bal for f in passing])
    return passing[_simplest(passing, gain, raw, bal, int(np.argmax(gain)), list(range(len(passing))), alpha)]


def bootstrap_inclusion(fitted: list[Fitted], n_blocks: int, n_tests: int, level: float, draws: int,
                        seed: int) -> dict[str, float]:
    """Share of block-bootstrap resamples (condition blocks drawn with replacement) in which each fitted
    mechanism is the one named (the largest balanced gain, or the simplest tied with it, :func:`_simplest`)
    among those whose whitened likelihood ratio on the resample passes ``level``/``n_tests`` and that lower the
    balanced misfit."""
    rng = np.random.default_rng(seed)
    raw = np.stack([f.block_raw for f in fitted])
    bal = np.stack([f.block_bal for f in fitted])
    wins: dict[str, int] = {}
    for _ in range(draws):
        pick = rng.integers(0, n_blocks, n_blocks)
        g = bal[:, pick].sum(axis=1)
        ok = [i for i, f in enumerate(fitted) if g[i] > 0
              and stats.chi2.sf(max(float(raw[i, pick].sum()), 0.0), f.dof) < level / n_tests]
        best = int(np.argmax(g))
        if best not in ok:
            continue
        f = fitted[_simplest(fitted, g, raw[:, pick], bal[:, pick], best, ok, level)]
        wins[f.candidate.mechanism] = wins.get(f.candidate.mechanism, 0) + 1
    return {m: w / draws for m, w in wins.items()}
