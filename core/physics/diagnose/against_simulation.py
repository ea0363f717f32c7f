"""The missing-physics finder against the user's own simulation (``thermodrift diagnose --simulation SIM``).

What is "left out" is defined relative to the user's simulation of the machine (an FE model or a lumped
network run on the recorded inputs): the part of measured minus simulated that imperfect parameters of that
simulation cannot produce and one mechanism's declared form can. Pipeline (:func:`diagnose_simulation`)::

    align        the simulation onto the recording's times (:mod:`.simulation_table`); its channels are the
                 recording's temperature and displacement channels it gives
    noise        per channel from the second differences of measured minus simulated (robust scale)
    null         the calibration null per channel (:func:`.sim_forms.null_design`): offset, simulated excess and
                 its lags, lagged speed heat where the simulation is heated, and the simulation's own response
                 to every recorded input it responds to with a lag of it, so a driver the simulation has with a
                 wrong gain or time constant is absorbed, not named. Fitted on the rows before the final block,
                 with a ridge on its columns (:data:`NULL_RIDGE`): the calibrated simulation, the ``baseline``
    test         every registered mechanism declaring ``simulation_form`` (:mod:`.sim_forms`): its driver through
                 each of its lags, a gain per channel it reaches, its sign on temperature channels; sensor lag
                 as a fixed form (each temperature channel reads the simulation plus its correction through a
                 first-order lag, never free derivative terms). A mechanism declaring none, or whose driver the
                 recording lacks, is untestable; one whose lagged driver the null's columns take whole
                 (:data:`.sim_forms.IN_NULL`) nested: the report says so with the reason
    decide       on held-out folds: the final block and :data:`FOLDS` contiguous groups of condition blocks
                 before it, each predicted by the null and by null + mechanism fitted without it (the lag chosen
                 on the training rows). Judged on the drift channels when the form reaches them, else on the
                 temperatures. A finding needs all three: per fold the share of the null's held-out error on its
                 judged channels it removes, with a median over the folds of :data:`GAIN_MIN` (a paired
                 comparison of null and null + mechanism fold by fold, robust to the one fold whose conditions
                 the others lack; :data:`GAIN_ALL` when every fold is better; judged on the drift, any median
                 when every fold is better by :data:`STEADY`, ranked after every other), consistency (at least
                 :data:`IMPROVED` folds better, the final block among them) and a size in noise units
                 (:data:`SIZE_MIN`); the temperature channels it reaches besides may not lose more than
                 :data:`GUARD`. One judged on the drift comes first. A rival judged alike (passing or not) with
                 :data:`RIVAL` of the best median gain (for one judged on the temperatures, any judged on the
                 drift too) makes it "cannot tell" (precision first: no name) unless the best beats it fold by
                 fold (a larger share on :data:`BEATS` of the folds) or is decisive against it: fitted together,
                 the best removes :data:`EXTRA_MIN` of what the rival leaves held out, and twice what the rival
                 removes of what the best leaves. A best driven by a recorded input must also beat that input
                 shifted in time (:func:`_shifted`)
    model        the winner fitted on the rows before the final block: simulation + null + its correction, its
                 gains per channel and its lag with finite intervals, the windows where it acts, and the
                 held-out fit before and after (``report.json`` keeps its shape)
"""

from __future__ import annotations

import time
import types
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from thermodrift.core.metrics import rms, rmse
from thermodrift.core.errors import InputError
from thermodrift.core.physics.diagnose import Diagnosis, check_input, final_cut, sim_forms
from thermodrift.core.physics.diagnose.simulation_table import align
from thermodrift.core.physics.diagnose.windows import condition_blocks, driver_windows, locate

GAIN_MIN = 0.6      # median over the folds of the share of the null's held-out error (noise units, judged
                    # channels) a finding removes: one fold extrapolating badly (speeds the others lack) does
                    # not sink a mechanism, and one fold explained well does not carry it
GAIN_ALL = 0.5      # ... or this median when every fold is better
STEADY = 0.05       # ... or, judged on the drift, every fold better by this share of its null error (a fixed lag
                    # on the temperatures improves any timing misfit a little everywhere: no such route there)
SIZE_MIN = 4.0      # its correction's peak-to-peak over the fitted rows, in noise units, on one judged channel
RIVAL = 0.8         # another mechanism judged alike with this median gain of the best's: cannot tell which
FOLDS = 8           # contiguous groups of condition blocks before the final block
NULL_RIDGE = 1e-3   # ridge on the null's columns (scaled to unit peak), of their mean energy: near-collinear lags
                    # of the simulated excess, speed heat and inputs otherwise take large cancelling gains that a
                    # mechanism's column reshuffles, and the shuffle extrapolates as a trend into held-out blocks
GUARD = 0.5         # the other channels it reaches may lose at most this share of their held-out fit
IMPROVED = 6        # at least this many of the FOLDS + 1 folds must be better
EXTRA_MIN = 0.1     # against a rival within RIVAL: share of what is left with the rival in that the best removes
BEATS = 7           # ... or the best removes a larger share of the null's held-out error than the rival on this
                    # many of the FOLDS + 1 folds (a paired comparison, fold by fold)


@dataclass
class Tested:
    """One mechanism's test: judged channels, held-out gain per fold (noise units), share, size, the fit."""

    mechanism: str
    form: dict
    judged: list[int]
    fold_gain: np.ndarray
    share: float                        # share of the null's held-out error removed, over all folds
    size: float
    guard: float
    tau_s: float
    correction: np.ndarray              # (samples, channels) of the full fit, the mechanism's part
    fitted: np.ndarray                  # (samples, channels) null + mechanism, full fit
    params: dict[str, float] = field(default_factory=dict)
    ci: dict[str, list[float]] = field(default_factory=dict)
    passed: bool = False
    reason: str = ""

    fold_null: np.ndarray = None        # the null's held-out error per fold on the judged channels

    @property
    def consistent(self) -> bool:
        """At least :data:`IMPROVED` folds better, the final block among them (the forward prediction a user
        compensates with), and a median gain of :data:`GAIN_MIN` (:data:`GAIN_ALL` when every fold is better)."""
        better = int((self.fold_gain > 0).sum())
        return bool(better >= IMPROVED and self.fold_gain[-1] > 0
                    and self.gain >= (GAIN_ALL if better == len(self.fold_gain) else GAIN_MIN))

    @property
    def steady(self) -> bool:
        """Every fold better by at least :data:`STEADY` of the null's held-out error there."""
        return bool((self.fold_share >= STEADY).all())

    def passes(self, on_drift: bool) -> bool:
        """Consistent (or steady, when judged on the drift), of :data:`SIZE_MIN` and within :data:`GUARD`."""
        return bool((self.consistent or on_drift and self.steady) and self.size >= SIZE_MIN
                    and self.guard >= -GUARD)

    @property
    def fold_share(self) -> np.ndarray:
        """Per fold, the share of the null's held-out error (judged channels) removed."""
        return self.fold_gain / np.maximum(self.fold_null, 1e-300)

    @property
    def gain(self) -> float:
        """Median over the folds of :attr:`fold_share`: the decision statistic."""
        return float(np.median(self.fold_share))


@dataclass
class Problem:
    """Everything the tests share: times, channels, measured and simulated readings, noise, rows and folds."""

    recording: Any
    channels: list[str]
    kinds: list[str]
    measured: np.ndarray
    sim: np.ndarray
    sigma: np.ndarray
    fit_rows: np.ndarray                # bool
    fold: np.ndarray                    # fold id per sample (−1: none; FOLDS: the final block)
    inputs: sim_forms.Inputs
    excess: np.ndarray                  # simulated excess per channel
    amb_excess: np.ndarray              # mean simulated temperature excess over ambient
    nulls: list[np.ndarray]             # null design per channel
    simulated: list[str]                # recorded inputs the simulation responds to
    detected: bool                      # read from its traces (True) or said by the user
    heated: np.ndarray                  # per channel: the simulation moves it with the spindle's heat
    cache: dict = field(default_factory=dict)  # designs by (channel, form, lag)

    @property
    def n_folds(self) -> int:
        return FOLDS + 1

    def train(self, f: int) -> np.ndarray:
        return self.fit_rows & (self.fold != f) if f < FOLDS else self.fit_rows


def _noise(r: np.ndarray, x: np.ndarray) -> float:
    """Noise scale of a residual: robust scale of its second differences, at least the readings' rounding."""
    d2 = np.diff(r, 2)
    s = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / np.sqrt(6.0)
    steps = np.abs(np.diff(x))
    q = float(steps[steps > 0].min()) / np.sqrt(12.0) if (steps > 0).any() else 0.0
    return max(s, q, 1e-9)


def _folds(recording, fit_rows: np.ndarray) -> np.ndarray:
    rows = np.flatnonzero(fit_rows)
    blocks = condition_blocks(recording, rows, min_blocks=FOLDS)
    fold = np.full(len(fit_rows), FOLDS)
    fold[rows] = np.minimum((blocks * FOLDS) // (int(blocks.max()) + 1), FOLDS - 1)
    return fold


def prepare(recording, simulation, simulated_inputs: list[str] | None = None) -> Problem:
    """The shared part of a diagnosis (see :class:`Problem`); ``simulation`` a frame as :func:`align` takes;
    ``simulated_inputs`` the recorded input roles the simulation was driven by (None: read from its traces)."""
    check_input(recording)
    sim_frame = align(simulation, recording)
    channels = [c for c in recording.channels if c in sim_frame.columns]
    kinds = [recording.channels[c].role for c in channels]
    measured = recording.data[channels].to_numpy(dtype=float)
    sim = sim_frame[channels].to_numpy(dtype=float)
    sigma = np.array([_noise(measured[:, j] - sim[:, j], measured[:, j]) for j in range(len(channels))])
    t = recording.time_s
    fit_rows = t < final_cut(recording)
    inputs = sim_forms.Inputs.of(recording)
    excess = sim - sim[0]
    temps = [j for j, k in enumerate(kinds) if k == "temperature"]
    amb = inputs.inputs.get("ambient", np.zeros(len(t)))
    amb_excess = (excess[:, temps].mean(axis=1) - amb) if temps else excess[:, 0] / max(np.ptp(excess[:, 0]), 1e-9)
    found = sim_forms.responses(inputs, excess, sigma)  # one pass: the heat rule and the inputs it responds to
    if simulated_inputs is None:
        simulated, detected = sim_forms.detect_inputs(found), True
    else:
        unknown = [r for r in simulated_inputs if r not in sim_forms.INPUT_ROLES]
        if unknown:
            raise InputError(f"unknown simulated input {unknown[0]!r}",
                             hint=f"use roles among {', '.join(sim_forms.INPUT_ROLES)}")
        simulated, detected = [r for r in simulated_inputs if r in inputs.inputs], False
    nulls = [sim_forms.null_design(inputs, excess[:, j], simulated, bool(found["speed"][j])) for j in range(len(channels))]
    return Problem(recording, channels, kinds, measured, sim, sigma, fit_rows, _folds(recording, fit_rows), inputs,
                   excess, amb_excess, nulls, simulated, detected, found["speed"])


def _solve(X: np.ndarray, y: np.ndarray, rows: np.ndarray, sign: int = 0, first: int = 0) -> np.ndarray:
    """Least squares on ``rows``; columns from ``first`` on held to ``sign`` (a wrong-signed one is dropped)."""
    Xr = X[rows]
    scale = np.maximum(np.abs(Xr).max(axis=0), 1e-12)
    A = Xr / scale
    G, b = A.T @ A, A.T @ y[rows]
    if first > 1:  # the null's columns (not its offset, not the mechanism's) held back: see NULL_RIDGE
        null = np.arange(1, first)
        G[null, null] += NULL_RIDGE * float(np.mean(np.diag(G)[null]))
    keep = np.ones(X.shape[1], bool)
    for _ in range(X.shape[1] - first + 1):
        beta = np.zeros(X.shape[1])
        idx = np.flatnonzero(keep)
        beta[idx] = sim_forms.ridge_solve(G[np.ix_(idx, idx)], b[idx]) / scale[idx]
        bad = [i for i in range(first, X.shape[1]) if keep[i] and sign * beta[i] < 0] if sign else []
        if not bad:
            return beta
        keep[bad[0]] = False
    return beta


def _design(p: Problem, j: int, form: dict | None, tau: float) -> tuple[np.ndarray, np.ndarray, int]:
    """(design, target, first mechanism column) of channel ``j``: the null, plus the form's lagged drivers."""
    key = (j, repr(sorted(form.items())) if form else None, tau)
    if key not in p.cache:
        p.cache[key] = _make_design(p, j, form, tau)
    return p.cache[key]


def _make_design(p: Problem, j: int, form: dict | None, tau: float) -> tuple[np.ndarray, np.ndarray, int]:
    Z, y = p.nulls[j], p.measured[:, j] - p.sim[:, j]
    if form is None or tau <= 0:
        return Z, y, Z.shape[1]
    if form["driver"] == "sensor_lag":  # fixed form: the channel reads simulation + correction through a lag
        lag = p.inputs.lag
        return np.column_stack([lag(z, tau) for z in Z.T]), p.measured[:, j] - lag(p.sim[:, j], tau), Z.shape[1]
    local = sim_forms.surfaces(p.inputs, p.excess, p.kinds, j, p.amb_excess)
    cols = [p.inputs.lag(x, tau) for x in sim_forms.drivers(form, p.inputs, p.excess[:, j], p.amb_excess, local)]
    return np.column_stack([Z, *cols]), y, Z.shape[1]


def _reached(p: Problem, form: dict, heat: bool = True) -> list[int]:
    """The channels a form acts on; with ``heat`` as :func:`.sim_forms.heat_nested` says."""
    kinds = form.get("reaches", ("temperature", "displacement"))
    axes = form.get("axes")
    out = []
    for j, (c, k) in enumerate(zip(p.channels, p.kinds)):
        if k not in kinds:
            continue
        if heat and (form["driver"] in sim_forms.HEAT_DRIVERS and not p.heated[j]
                     or form["driver"] == "bending" and p.heated[j]):
            continue
        if k == "displacement" and axes:
            axis = p.recording.channels[c].meta.get("axis")
            if axis is not None and axis not in axes:
                continue
        out.append(j)
    return out


def _fit_channel(p: Problem, j: int, form: dict | None, taus, train: np.ndarray):
    """Best lag for channel ``j`` on ``train`` rows: (tau, beta, design, target, first, weighted train SSE)."""
    sign = int(form.get("sign", 0)) * (1 if p.kinds[j] == "temperature" else sim_forms.sense(  # the physical sign
        p.excess, p.kinds, j) if form.get("drift_sense") else 0) if form else 0
    best = None
    for tau in taus:
        X, y, first = _design(p, j, form, tau)
        beta = _solve(X, y, train, sign, first)
        sse = float(np.sum((y[train] - X[train] @ beta) ** 2)) / p.sigma[j] ** 2
        if best is None or sse < best[-1]:
            best = (tau, beta, X, y, first, sse)
    return best


def _null_sse(p: Problem) -> np.ndarray:
    """Held-out SSE (noise units) of the null per fold and channel."""
    out = np.zeros((p.n_folds, len(p.channels)))
    for f in range(p.n_folds):
        test, train = p.fold == f, p.train(f)
        for j in range(len(p.channels)):
            _, beta, X, y, _, _ = _fit_channel(p, j, None, [0.0], train)
            out[f, j] = np.sum((y[test] - X[test] @ beta) ** 2) / p.sigma[j] ** 2
    return out


def assess_form(p: Problem, mechanism: str, form: dict, null_sse: np.ndarray) -> Tested:
    """Held-out test of one mechanism's form (see the module docstring)."""
    reached = _reached(p, form)
    taus = tuple(form.get("taus_s", (3600.0,)))
    lagged = form["driver"] == "sensor_lag"
    judged = ([j for j in reached if p.kinds[j] == "displacement"] or reached)
    if lagged:  # sensor lag: each channel its own lag, none where no lag fits its training rows better
        sse = np.zeros((p.n_folds, len(p.channels)))
        for f in range(p.n_folds):
            test, train = p.fold == f, p.train(f)
            for j in reached:
                _, beta, X, y, _, _ = _fit_channel(p, j, form, (0.0, *taus), train)
                sse[f, j] = np.sum((y[test] - X[test] @ beta) ** 2) / p.sigma[j] ** 2
    else:  # one lag for every reached channel, the one the training rows choose
        sse = _shared_lag(p, form, reached, taus)
    gain = null_sse - sse
    fold_gain = gain[:, judged].sum(axis=1)
    share = float(fold_gain.sum() / max(null_sse[:, judged].sum(), 1e-300))
    others = [j for j in reached if j not in judged]
    guard = float(gain[:, others].sum() / max(null_sse[:, others].sum(), 1e-300)) if others else 0.0
    n, c = p.measured.shape
    corr, fitted = np.zeros((n, c)), np.zeros((n, c))
    params, ci = {}, {}
    tau_all = _shared_tau(p, form, reached, taus, p.fit_rows) if not lagged else 0.0
    for j in range(c):
        if j not in reached:
            _, beta, X, y, _, _ = _fit_channel(p, j, None, [0.0], p.fit_rows)
            fitted[:, j] = p.sim[:, j] + X @ beta
            continue
        tau, beta, X, y, first, _ = _fit_channel(p, j, form, (0.0, *taus) if lagged else (tau_all,), p.fit_rows)
        pred = X @ beta
        if lagged:
            base = _fit_channel(p, j, None, [0.0], p.fit_rows)
            corr[:, j] = (p.measured[:, j] - y + pred) - (p.sim[:, j] + base[2] @ base[1])
            fitted[:, j] = p.measured[:, j] - y + pred
            if tau > 0:
                params[f"lag_s[{p.channels[j]}]"] = tau
                ci[f"lag_s[{p.channels[j]}]"] = list(sim_forms.grid_interval(taus, tau))
            continue
        corr[:, j] = X[:, first:] @ beta[first:]
        fitted[:, j] = p.sim[:, j] + pred
        for k in range(first, X.shape[1]):
            name = f"gain{'' if X.shape[1] - first == 1 else k - first}[{p.channels[j]}]"
            params[name] = float(beta[k])
            ci[name] = list(sim_forms.gain_interval(X, p.measured[:, j] - p.sim[:, j] - pred, beta, k, p.fit_rows))
    if not lagged:
        params["tau_s"] = tau_all
        ci["tau_s"] = list(sim_forms.grid_interval(taus, tau_all))
    rows = p.fit_rows
    size = max((float(np.ptp(corr[rows, j])) / p.sigma[j] for j in judged), default=0.0)
    return Tested(mechanism, form, judged, fold_gain, share, size, guard, tau_all, corr, fitted, params, ci,
                  fold_null=null_sse[:, judged].sum(axis=1))


def _shared_tau(p: Problem, form: dict, reached: list[int], taus, train: np.ndarray) -> float:
    best = None
    for tau in taus:
        sse = sum(_fit_channel(p, j, form, (tau,), train)[-1] for j in reached)
        if best is None or sse < best[1]:
            best = (tau, sse)
    return best[0]


def _shared_lag(p: Problem, form: dict, reached: list[int], taus) -> np.ndarray:
    sse = np.zeros((p.n_folds, len(p.channels)))
    for f in range(p.n_folds):
        test, train = p.fold == f, p.train(f)
        tau = _shared_tau(p, form, reached, taus, train)
        for j in reached:
            _, beta, X, y, _, _ = _fit_channel(p, j, form, (tau,), train)
            sse[f, j] = np.sum((y[test] - X[test] @ beta) ** 2) / p.sigma[j] ** 2
    return sse


def diagnose_simulation(recording, simulation, *, simulated_inputs: list[str] | None = None, registry=None,
                        seed: int = 0, only: list[str] | None = None) -> Diagnosis:
    """Find what ``recording`` holds that the user's ``simulation`` (a frame indexed by time in s, or with a
    ``time_s`` column; columns the recording's temperature and displacement channels) leaves out; see the
    module docstring. ``simulated_inputs``: the recorded input roles (ambient, coolant_inlet, cutting_power,
    axis_velocity) that drove the simulation (None: read from its traces, :func:`.sim_forms.detect_inputs`).
    ``seed`` is kept for the interface (every step here is deterministic)."""
    clock = time.perf_counter()
    if registry is None:
        from thermodrift.core import registry as reg_module
        registry = reg_module.default()
    p = prepare(recording, simulation, simulated_inputs)
    null_sse = _null_sse(p)
    tested, status = [], []
    for mid in registry.names("mechanism"):
        if only is not None and mid not in only:
            continue
        form = sim_forms.form_of(registry.get("mechanism", mid).factory)
        if form is None:
            status.append({"mechanism": mid, "status": "untestable",
                           "reason": "untestable against a simulation: it declares no form for this mode"})
            continue
        why = sim_forms.missing(form, p.inputs)
        if why is None and form["driver"] in p.simulated:
            status.append({"mechanism": mid, "status": "nested", "reason": (
                f"nested in the calibrated simulation: the simulation already responds to {form['driver']} "
                f"({'read from its traces' if p.detected else 'as given'}), and a mechanism driven by it cannot be "
                "told from that path with a wrong gain or lag")})
            continue
        if why is None and not _reached(p, form):
            if _reached(p, form, heat=False):
                status.append({"mechanism": mid, "status": "nested", "reason": sim_forms.heat_nested(form)})
                continue
            why = "none of the channels it reaches is in the simulation"
        if why:
            status.append({"mechanism": mid, "status": "untestable", "reason": f"untestable: {why}"})
            continue
        if (left := _outside_null(p, form)) < sim_forms.IN_NULL:
            status.append({"mechanism": mid, "status": "nested", "reason": (
                "nested in the calibrated simulation's null: the null's columns (the simulated excess and speed heat "
                f"lagged up to 10 h) take its lagged driver whole ({left:.1%} left at most), so no held-out test "
                "can tell it from a parameter error of the simulation")})
            continue
        tested.append(assess_form(p, mid, form, null_sse))
    for t in tested:
        on_drift = p.kinds[t.judged[0]] == "displacement"
        t.passed = t.passes(on_drift)
        t.reason = _why(t, on_drift)
    passing = sorted([t for t in tested if t.passed], key=lambda t: -t.gain)
    main = [t for t in passing if t.consistent]  # the drift first (what a compensation predicts), steady last
    pool = [t for t in main if p.kinds[t.judged[0]] == "displacement"] or main or passing
    win = pool[0] if pool else None
    # a rival: any other mechanism judged alike explaining as much held out, passing or not (one failing only on
    # its folds is still an explanation the data does not rule out); a winner judged on the temperatures alone
    # also has every drift-judged one as a rival (the drift misfit cannot be named while a drift form explains it)
    rivals = [t for t in tested if win and t is not win and t.gain >= RIVAL * win.gain
              and p.kinds[t.judged[0]] in (p.kinds[win.judged[0]], "displacement") and not _beats(win, t)
              and not _decisive(p, win, t, null_sse)]
    shifted = _shifted(p, win, null_sse) if win and not rivals else None
    if shifted is not None:
        rivals = [shifted]
    base_fit = _baseline(p)
    findings, rejected = [], []
    if win and not rivals:
        findings.append(_finding(p, win, null_sse))
    for t in tested:
        if t is win and not rivals:
            continue
        reason = t.reason
        if shifted is not None and t is win:
            reason = (f"cannot tell: its driver shifted in time ({shifted.mechanism}) explains the held-out misfit "
                      f"as well (median fold gain {shifted.gain:.0%} against {t.gain:.0%})")
        elif rivals and t in [win, *rivals]:
            reason = ("cannot tell: " + ", ".join(x.mechanism for x in [win, *rivals] if x is not t)
                      + f" explains the held-out misfit as well (median fold gain {t.gain:.0%}, within {RIVAL:.0%} of the "
                      "best)")
        elif t.passed:
            reason = (f"explains less than {win.mechanism} (median fold gain {t.gain:.0%} against {win.gain:.0%} "
                      "of the held-out misfit)")
        rejected.append({"mechanism": t.mechanism, "reason": "tested: " + reason})
    rejected += [{"mechanism": s["mechanism"], "reason": s["reason"]} for s in status]
    augmented = win.fitted if findings else base_fit
    adequacy = _adequacy(p, base_fit, null_sse, tested, status)
    net = types.SimpleNamespace(name="simulation (calibrated)")
    return Diagnosis(p.channels, p.kinds, recording.time_s, p.measured, base_fit, augmented, p.fit_rows, findings,
                     rejected, driver_windows(recording), net, net, len(tested), time.perf_counter() - clock,
                     recording.speed.to_numpy(dtype=float), [], adequacy)


def _outside_null(p: Problem, form: dict) -> float:
    """The largest share of the form's lagged driver, over its lags and the channels it reaches, that the null
    leaves unexplained on the fitted rows (:func:`.sim_forms.outside`; sensor lag, a fixed form: 1)."""
    designs = [] if form["driver"] == "sensor_lag" else [
        _design(p, j, form, tau) for j in _reached(p, form) for tau in form.get("taus_s", (3600.0,))]
    return max((sim_forms.outside(X, first, p.fit_rows) for X, _, first in designs), default=1.0)


def _pair_sse(p: Problem, parts: list[Tested], judged: list[int]) -> float:
    """Held-out error (noise units, summed over the folds and ``judged`` channels) of the null plus every form
    of ``parts`` together, each at the lag its own fit chose."""
    total = 0.0
    for f in range(p.n_folds):
        test, train = p.fold == f, p.train(f)
        for j in judged:
            Z, y, first = _design(p, j, None, 0.0)
            cols = [Z] + [_design(p, j, t.form, t.tau_s)[0][:, first:] for t in parts]
            X = np.column_stack(cols)
            signs = {int(t.form.get("sign", 0)) for t in parts}
            sign = signs.pop() if len(signs) == 1 and p.kinds[j] == "temperature" else 0
            beta = _solve(X, y, train, sign, first)
            total += float(np.sum((y[test] - X[test] @ beta) ** 2)) / p.sigma[j] ** 2
    return total


def _shifted(p: Problem, win: Tested, null_sse: np.ndarray) -> Tested | None:
    """The winner's form with its recorded input circularly shifted by a third and two thirds of the recording,
    when one such explains :data:`RIVAL` of its median fold gain (a slow input fits any slow misfit through a
    free lag; a real path fits its own timing better), else None. Speed-driven forms are not shifted."""
    if win.form["driver"] not in sim_forms.INPUT_ROLES:
        return None
    n = len(p.recording.time_s)
    for k in (n // 3, 2 * n // 3):
        t = assess_form(p, f"{win.mechanism} shifted {k} rows", dict(win.form, shift_rows=k), null_sse)
        if t.gain >= RIVAL * win.gain:
            return t
    return None


def _beats(win: Tested, rival: Tested) -> bool:
    """Whether ``win`` removes a larger share of the null's held-out error than ``rival`` on :data:`BEATS` of the
    folds (sensor lag, judged on other channels, is never compared)."""
    if "sensor_lag" in (win.form["driver"], rival.form["driver"]):
        return False
    return int((win.fold_share > rival.fold_share).sum()) >= BEATS


def _decisive(p: Problem, win: Tested, rival: Tested, null_sse: np.ndarray) -> bool:
    """Whether ``win`` removes at least :data:`EXTRA_MIN` of what is left held out once ``rival`` is in the
    model, and twice the share ``rival`` removes once ``win`` is in (sensor lag, a fixed form, is never
    paired: it is judged on other channels)."""
    if "sensor_lag" in (win.form["driver"], rival.form["driver"]):
        return False
    judged = win.judged
    alone_w, alone_r = _pair_sse(p, [win], judged), _pair_sse(p, [rival], judged)
    both = _pair_sse(p, [win, rival], judged)
    extra_w = (alone_r - both) / max(alone_r, 1e-300)
    extra_r = (alone_w - both) / max(alone_w, 1e-300)
    return extra_w >= EXTRA_MIN and extra_w >= 2 * extra_r


def _baseline(p: Problem) -> np.ndarray:
    """The calibrated simulation: simulation + null fitted on the rows before the final block."""
    out = np.zeros_like(p.sim)
    for j in range(len(p.channels)):
        _, beta, X, _, _, _ = _fit_channel(p, j, None, [0.0], p.fit_rows)
        out[:, j] = p.sim[:, j] + X @ beta
    return out


def _why(t: Tested, on_drift: bool) -> str:
    text = (f"median fold gain {t.gain:.0%} of the calibrated simulation's held-out misfit on its judged channels "
            f"(over all folds {t.share:.0%}), {int((t.fold_gain > 0).sum())} of {len(t.fold_gain)} folds improved"
            f"{'' if t.fold_gain[-1] > 0 else ' (not the final block)'}, size {t.size:.3g} noise units")
    if t.passed:
        return text
    fails = []
    if (t.fold_gain > 0).sum() < IMPROVED:
        fails.append(f"fewer than {IMPROVED} folds improved")
    elif t.fold_gain[-1] <= 0:
        fails.append("the final block not improved")
    elif not (t.consistent or (on_drift and t.steady)):
        fails.append(f"median fold gain below {GAIN_MIN:.0%} ({GAIN_ALL:.0%} with every fold improved, or any "
                     f"with every fold by {STEADY:.0%} on the drift)")
    if t.size < SIZE_MIN:
        fails.append(f"size below {SIZE_MIN:g} noise units")
    if t.guard < -GUARD:
        fails.append(f"worse on its other channels ({t.guard:.0%})")
    return text + ": " + "; ".join(fails)


def _where(p: Problem, t: Tested) -> dict[str, list]:
    """The finding's ``where`` and ``_windows`` (:func:`.windows.locate`) on its judged channels."""
    gain = (p.measured - t.fitted + t.correction) ** 2 - (p.measured - t.fitted) ** 2
    return locate(p.recording.time_s, gain, p.channels, t.judged, driver_windows(p.recording))


def _finding(p: Problem, t: Tested, null_sse: np.ndarray) -> dict[str, Any]:
    where = _where(p, t)
    final = ~p.fit_rows
    base = _baseline(p)
    before = {p.channels[j]: float(rmse(p.measured[final, j], base[final, j])) for j in t.judged}
    after = {p.channels[j]: float(rmse(p.measured[final, j], t.fitted[final, j])) for j in t.judged}
    improved = int((t.fold_gain > 0).sum())
    fit = "; ".join(f"{c} {before[c]:.3g} → {after[c]:.3g}" for c in before)
    evidence = (f"{t.mechanism} ({t.form['driver']} through a first-order lag) removes a median {t.gain:.0%} per "
                f"held-out fold ({t.share:.0%} over all) of the calibrated simulation's misfit on its judged "
                f"channels ({', '.join(p.channels[j] for j in t.judged)}), improves {improved} of "
                f"{len(t.fold_gain)} held-out folds{' including the final block' if t.fold_gain[-1] > 0 else ''}, "
                f"and its correction's peak-to-peak is {t.size:.3g} times the noise; the "
                f"calibration null (simulated excess and its lags, lagged speed heat, the simulation's response to "
                f"each recorded input it responds to) does not explain it. Held-out RMSE on the final block: {fit}")
    return {"mechanism": t.mechanism, "confidence": round(improved / len(t.fold_gain), 3),
            "parameters": {k: float(f"{v:.6g}") for k, v in t.params.items()},
            "ci": {k: [float(f"{min(v[0], t.params[k]):.6g}"), float(f"{max(v[1], t.params[k]):.6g}")]
                   for k, v in t.ci.items()},
            **where,
            "evidence": evidence + ".",
            "test": "median over held-out folds (the final block and contiguous condition blocks) of the share "
                    "of the calibrated simulation's misfit removed, with fold consistency and size in noise units",
            "statistic": round(t.gain, 4), "dof": len(t.params), "p_value": 1.0, "fdr_level": 0.0,
            "fixed": {}, "label": f"{t.mechanism} (tau_s={t.tau_s:g})" if t.tau_s else t.mechanism,
            "route": "median held-out fold gain, folds and size", "_gain_share": t.share}


def _adequacy(p: Problem, base: np.ndarray, null_sse: np.ndarray, tested: list[Tested], status: list[dict]):
    """The report's adequacy block, for the calibrated simulation, and every mechanism's status."""
    final = ~p.fit_rows
    chans = {}
    for j, c in enumerate(p.channels):
        if p.kinds[j] != "displacement":
            continue
        r = (p.measured[:, j] - base[:, j])
        fit_rmse = float(rms(r[p.fit_rows]))
        val = float(rms(r[final]))
        rf = r[p.fit_rows] - r[p.fit_rows].mean()
        chans[c] = {"rmse_um": fit_rmse, "noise_um": float(p.sigma[j]),
                    "misfit_over_noise": fit_rmse / float(p.sigma[j]), "validation_rmse_um": val,
                    "validation_over_fitted": round(val / max(fit_rmse, 1e-12), 3),
                    "residual_ar_sum": float(np.dot(rf[1:], rf[:-1]) / max(np.dot(rf, rf), 1e-300))}
    listing = [{"mechanism": t.mechanism, "status": "tested", "share": round(t.share, 4), "gain": round(t.gain, 4),
                "folds_improved": int((t.fold_gain > 0).sum()), "size_noise_units": round(t.size, 3),
                "fold_share": [round(float(v), 4) for v in t.fold_share], "passed": t.passed, "reason": t.reason}
               for t in tested]
    return {"mode": "simulation", "channels": chans, "structural": False, "simulated_inputs": p.simulated,
            "simulated_inputs_from": "traces" if p.detected else "user",
            "mechanisms": listing + [{"mechanism": s["mechanism"], "status": s["status"], "reason": s["reason"]}
                                     for s in status]}
