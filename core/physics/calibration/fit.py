"""``calibrate``: the search, its stop rule, multi-start, the never-worse guard, and the result."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd
from scipy import optimize
from threadpoolctl import ThreadpoolController

from thermodrift.core import metrics
from thermodrift.core.errors import InputError
from thermodrift.core.physics.calibration.auto import AUTO_AMBIENT_DEGC, auto_network
from thermodrift.core.physics.calibration.free import FreeParameter, default_free, free_from_paths
from thermodrift.core.physics.calibration.objective import MAX_FIT_SAMPLES, Problem, frame_of
from thermodrift.core.physics.calibration.prior import Prior, choose_strength, prior_scale
from thermodrift.core.physics.calibration.uncertainty import Estimate, jacobian, num, uncertainty
from thermodrift.core.physics.network import Network

# Small dense algebra (≤ 20 nodes) is fastest single-threaded; a BLAS pool on a busy machine made lstsq 7× slower.
_THREADS = ThreadpoolController()
FTOL, XTOL, GTOL = 1e-6, 1e-8, 1e-8   # least_squares tolerances (relative cost change, step, gradient)
WORSE_TOLERANCE = 0.05               # a displacement RMSE above (1 + this) × its start value counts as worse
JITTER_LOG = 0.5                      # σ of the log-normal jitter of extra starts (±65 % at 1σ)
# Least ridge strength (per sample, standardised sensitivities) of the auto network's expansion map. Unpenalised,
# the map turns the difference of two nearly equal node trajectories into a regressor of any size: on FL_THERMAL
# moving one conductance by 1e-5 (relative) from a value another node shares cut the cost by 13 %, so the
# objective is rough at the search's finite-difference step and the search stalls where it starts.
AUTO_MIN_RIDGE = 1e-8


@dataclass
class CalibrationResult:
    """Everything a calibration found; :meth:`to_dict` is what ``calibration.json`` holds.

    ``rmse_initial``/``rmse``: per channel on every sample (K, µm), at the start and the calibrated point.
    ``stop``: ``"tolerance"``, ``"evaluation_cap"`` or ``"no_free_parameters"`` (of the start that was kept);
    ``stopped`` the optimizer's message. ``starts``: one record per start (cost, stop, evaluations, θ);
    ``spread``: max/min cost over starts and per-parameter max/min value. ``warnings``: temperature channels
    that got worse, a start kept because the fit worsened a displacement channel, a capped fit grid.
    ``prior``: the Gaussian prior on the nonlinear parameters (:mod:`.prior`), None without one; ``cost`` and
    ``cost_initial`` are of the data alone, the costs in ``starts`` include the prior.
    """

    network_initial: Network
    network: Network
    estimates: list[Estimate]
    linear: dict[str, dict[str, float]]            # channel -> offset / sensitivities / projected heat
    linear_ci: dict[str, dict[str, list]]          # displacement channel -> name -> [low, high]
    ridge: dict[str, float]                        # displacement channel -> ridge strength (λ per sample)
    sigma: dict[str, float]                        # channel -> noise σ (K or µm)
    weight: dict[str, float]                       # channel -> σ its residual was divided by (≥ noise σ)
    rmse_initial: dict[str, float]
    rmse: dict[str, float]
    unidentifiable: list[dict[str, Any]]
    null_directions: list[dict[str, Any]]
    level: float
    cost_initial: float
    cost: float
    s2: float
    evaluations: int
    seconds: float
    stop: str
    stopped: str
    starts: list[dict[str, Any]]
    spread: dict[str, Any]
    grid_step_s: float
    fit_samples: int
    warnings: list[str] = field(default_factory=list)
    assumptions: tuple[str, ...] = ()
    time_s: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False)
    measured: pd.DataFrame | None = field(default=None, repr=False)
    predicted_initial: pd.DataFrame | None = field(default=None, repr=False)
    predicted: pd.DataFrame | None = field(default=None, repr=False)
    channel_kind: dict[str, str] = field(default_factory=dict)
    speed_rpm: np.ndarray | None = field(default=None, repr=False)
    prior: Prior | None = None

    @property
    def residuals(self) -> pd.DataFrame:
        """Measured minus calibrated prediction (K, µm) per channel, every sample."""
        return self.measured - self.predicted

    def estimate(self, name: str) -> Estimate:
        return next(e for e in self.estimates if e.name == name)

    def to_dict(self) -> dict[str, Any]:
        return {
            "network": self.network.name,
            "description": self.network.description,
            "rmse_initial": self.rmse_initial,
            "rmse": self.rmse,
            "warnings": self.warnings,
            "assumptions": list(self.assumptions),
            "confidence_level": self.level,
            "estimates": {e.name: {"value": e.value, "ci": [num(e.low), num(e.high)], "start": e.start,
                                   "unit": e.unit, "log": e.log, "se": num(e.se), "ci_ratio": num(e.ratio),
                                   "at_bound": e.at_bound, "paths": list(e.paths)} for e in self.estimates},
            "linear": self.linear,
            "linear_ci": self.linear_ci,
            "ridge": self.ridge,
            "unidentifiable": self.unidentifiable,
            "null_directions": self.null_directions,
            "noise_sigma": self.sigma,
            "weight_sigma": self.weight,
            "objective": {"initial": self.cost_initial, "final": self.cost, "s2": self.s2,
                          "evaluations": self.evaluations, "seconds": round(self.seconds, 3),
                          "stop": self.stop, "stopped": self.stopped, "grid_step_s": self.grid_step_s,
                          "fit_samples": self.fit_samples},
            "starts": self.starts,
            "spread": self.spread,
            "prior": self.prior.to_dict() if self.prior else None,
        }


def calibrate(recording, network: Network | None = None, *,
              free: Sequence[FreeParameter] | Sequence[str] | None = None, targets: Sequence[str] | None = None,
              hidden_nodes: int | tuple[float, ...] = 2, max_evaluations: int = 100, starts: int = 1, seed: int = 0,
              level: float = 0.95, max_fit_samples: int = MAX_FIT_SAMPLES, intervals: bool = True,
              progress: bool = False, jitter_seed: int | None = None, grouped: bool = False,
              prior_strength: float | None = None) -> CalibrationResult:
    """Calibrate ``network`` (None: the ``auto`` network of the recording) to ``recording``.

    ``free``: FreeParameter objects (a mechanism adds its own), or glob patterns over parameter paths
    (default: the auto network's own set, else :func:`default_free`). ``targets``: displacement channels to fit
    (default all that a sensor reads). The search stops on its tolerances or after ``max_evaluations``
    iterations of each start — never on wall-clock time, so the same inputs give the same result however loaded
    the machine is. ``starts`` > 1 adds starts jittered from ``seed``; the lowest cost that leaves no
    displacement channel worse than the start is kept. ``jitter_seed``: the first search starts from the start
    jittered from this seed (the never-worse guard still compares with the unjittered start), so the spread of
    results over seeds measures how much a fit depends on where it starts. ``level`` is the interval confidence;
    ``intervals=False`` skips the final Jacobian. ``grouped``: the auto network with one conductance factor per
    node group (:func:`auto_network`). ``prior_strength``: λ per data row of a Gaussian prior on the nonlinear
    parameters centred on the network's start (:mod:`.prior`); None: chosen on a held-out block for the auto
    network, none for a given network; 0: none. Raises InputError when a calibrated displacement error exceeds
    the channel's range.
    """
    with _THREADS.limit(limits=1, user_api="blas"):
        return _calibrate(recording, network, free, targets, hidden_nodes, max_evaluations, starts, seed, level,
                          max_fit_samples, intervals, progress, jitter_seed, grouped, prior_strength)


def _least_squares(fun, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_evaluations: int):
    """The calibration's search: trust-region reflective least squares within [lo, hi], stopped on
    :data:`FTOL`/:data:`XTOL`/:data:`GTOL` or after ``max_evaluations`` evaluations."""
    return optimize.least_squares(fun, x0, bounds=(lo, hi), x_scale=1.0, method="trf", max_nfev=max_evaluations,
                                  xtol=XTOL, ftol=FTOL, gtol=GTOL, diff_step=1e-4)


def _calibrate(recording, network, free, targets, hidden_nodes, max_evaluations, starts, seed, level,
               max_fit_samples, intervals, progress, jitter_seed, grouped, prior_strength) -> CalibrationResult:
    clock = time.perf_counter()  # reported only; no decision depends on it
    assumptions: tuple[str, ...] = ()
    taus: list[float] = []
    is_auto = network is None
    if is_auto:
        auto = auto_network(recording, hidden_nodes=hidden_nodes, grouped=grouped)
        network, default = auto.network, auto.free
        assumptions, taus = auto.assumptions, list(auto.time_constants_s.values())
    else:
        default = None
    if free is None:
        free = default if default is not None else default_free(network)
    elif free and isinstance(free[0], str):
        free = free_from_paths(network, list(free))
    problem = Problem(network, list(free), recording, targets, taus, max_fit_samples, AUTO_AMBIENT_DEGC,
                      AUTO_MIN_RIDGE if is_auto else 0.0)
    warnings: list[str] = []
    if problem.grid_step_s > 0 and len(problem.rows) >= max_fit_samples:
        warnings.append(f"fit grid capped at {max_fit_samples} samples: step {problem.grid_step_s:g} s is coarser "
                        "than the recording's time scales ask for")
    lo, hi = problem.bounds
    theta0 = np.clip(problem.theta0, lo, hi)
    problem.choose_ridge(theta0)
    problem.set_weights(theta0)
    r0 = problem.residuals(theta0)
    prior = None
    if problem.free and (prior_strength is None and is_auto or prior_strength):
        if prior_strength is None:
            strength, validation = choose_strength(problem, recording, theta0,
                                                   lambda f, x0: _least_squares(f, x0, lo, hi, max_evaluations).x)
        else:
            strength, validation = float(prior_strength), {"given": True}
        prior = Prior([p.name for p in problem.free], theta0, prior_scale(problem), strength, len(r0), validation)
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(desc="calibrate", unit="sim", leave=False)

    def fun(theta: np.ndarray) -> np.ndarray:
        r = problem.residuals(theta)
        if bar is not None:
            bar.update()
        return r if prior is None else np.concatenate([r, prior.residuals(theta)])

    def search(x0: np.ndarray) -> dict[str, Any]:
        before = problem.evaluations
        sol = _least_squares(fun, x0, lo, hi, max_evaluations)
        return {"theta": np.array(sol.x), "cost": float(sol.fun @ sol.fun), "stopped": sol.message,
                "stop": "evaluation_cap" if sol.status == 0 else "tolerance",
                "evaluations": problem.evaluations - before}

    rng = np.random.default_rng(seed)
    runs: list[dict[str, Any]] = []
    if not problem.free:
        runs.append({"theta": theta0, "cost": float(r0 @ r0), "stop": "no_free_parameters",
                     "stopped": "no nonlinear parameters", "evaluations": 0})
    else:
        # weights re-read at the first optimum (the start's misfit is mostly the start's error), then fixed
        # for every start so their costs compare
        first = search(theta0 if jitter_seed is None else np.clip(
            theta0 + np.random.default_rng(jitter_seed).normal(0.0, 1.0, len(theta0)) * _jitter(problem, lo, hi),
            lo, hi))
        problem.set_weights(first["theta"])
        r0 = problem.residuals(theta0)
        refined = search(first["theta"])
        refined["evaluations"] += first["evaluations"]
        runs.append(refined)
        for _ in range(1, max(1, starts)):
            runs.append(search(np.clip(theta0 + rng.normal(0.0, 1.0, len(theta0)) * _jitter(problem, lo, hi),
                                       lo, hi)))
    if bar is not None:
        bar.close()
    # the never-worse guard: the best run whose displacement channels are all at least as good as at the start.
    # Start and runs are compared at the ridge strength the search minimised (chosen at the start): re-choosing
    # it at a run judges the run by an objective it did not minimise (on FL_THERMAL a stronger ridge at the fit
    # made every fit look 5-18 % worse than the start, though at equal strength it improves every channel).
    start = _full(problem, theta0)
    chosen, full = None, None
    for run in sorted(runs, key=lambda r: r["cost"]):
        if run["cost"] > float(r0 @ r0):
            continue
        cand = _full(problem, run["theta"])
        worse = [c for c in cand["rmse"] if problem_kind(problem, c) == "displacement"
                 and cand["rmse"][c] > start["rmse"][c] * (1 + WORSE_TOLERANCE)]
        if not worse:
            chosen, full = run, cand
            break
        warnings.append(f"a fit with cost {run['cost']:.4g} left {', '.join(worse)} worse than the start on the "
                        "full recording; not kept")
    if chosen is None:
        chosen = {"theta": theta0, "cost": float(r0 @ r0), "stop": runs[0]["stop"],
                  "stopped": "start kept: no fit improved every displacement channel", "evaluations": 0}
        full = start
    theta = chosen["theta"]
    for c in full["rmse"]:
        if problem_kind(problem, c) == "temperature" and full["rmse"][c] > start["rmse"][c] * 1.01:
            warnings.append(f"temperature channel {c} got worse: {start['rmse'][c]:.4g} -> {full['rmse'][c]:.4g} K")
    for c, v in full["rmse"].items():
        span = float(np.ptp(problem.measured[c]))
        if problem_kind(problem, c) == "displacement" and v > span:
            raise InputError(f"{recording.source}: calibrated error of {c} is {v:.4g} µm, larger than the channel's "
                             f"range {span:.4g} µm — the network cannot describe this recording",
                             hint="check the manifest's roles and units, or calibrate a network spec (--network)")
    sim, out = full["sim_fit"], full["out_fit"]
    r = problem.weighted(out["predictions"])
    dof = max(len(r) - len(problem.free) - problem.n_linear, 1)
    s2 = float(r @ r) / dof
    if intervals:
        J = jacobian(problem.residuals, theta, lo, hi) if problem.free else np.zeros((len(r), 0))
        estimates, unidentifiable, null_dirs, linear_ci = uncertainty(problem, theta, J, s2, dof, level, lo, hi,
                                                                      sim, out)
    else:
        estimates = [Estimate(p.name, p.paths, p.from_search(v), p.value, math.nan, math.nan, math.nan, False,
                              p.unit, p.log) for p, v in zip(problem.free, theta)]
        estimates += [Estimate(p.name, p.paths, out["linear"][ch][p.name], p.value, math.nan, math.nan, math.nan,
                               False, p.unit) for ch, p in problem.projected.items()]
        unidentifiable, null_dirs, linear_ci = [], [], {}
    selection = prior.validation.get("evaluations", 0) if prior else 0
    costs = [run["cost"] for run in runs]
    values = np.array([[p.from_search(v) for p, v in zip(problem.free, run["theta"])] for run in runs])
    spread = {"cost_max_over_min": max(costs) / min(costs) if min(costs) > 0 else math.inf,
              "parameter_max_over_min": {p.name: float(values[:, i].max() / values[:, i].min())
                                         if values[:, i].min() > 0 else None for i, p in enumerate(problem.free)}}
    return CalibrationResult(
        network_initial=with_linear(problem.network_at(theta0, problem.heat(start["linear"])), start["linear"],
                                    problem),
        network=with_linear(problem.network_at(theta, problem.heat(out["linear"])), out["linear"], problem),
        estimates=estimates, linear=out["linear"], linear_ci=linear_ci,
        ridge={s.name: problem.ridge[names] for names, ss in problem.groups.items() for s in ss},
        sigma={c.name: c.sigma for c in problem.channels}, weight={c.name: c.weight for c in problem.channels},
        rmse_initial=start["rmse"], rmse=full["rmse"],
        unidentifiable=unidentifiable, null_directions=null_dirs, level=level, cost_initial=float(r0 @ r0),
        cost=float(r @ r), s2=s2,
        evaluations=problem.evaluations + selection, seconds=time.perf_counter() - clock,
        stop=chosen["stop"], stopped=chosen["stopped"],
        starts=[{"cost": run["cost"], "stop": run["stop"], "evaluations": run["evaluations"],
                 "values": {p.name: p.from_search(v) for p, v in zip(problem.free, run["theta"])}} for run in runs],
        spread=spread, grid_step_s=problem.grid_step_s, fit_samples=len(problem.rows), warnings=warnings,
        assumptions=assumptions, time_s=problem.time_s, measured=frame_of(problem, problem.measured),
        predicted_initial=start["predicted"], predicted=full["predicted"],
        channel_kind={c.name: c.kind for c in problem.channels},
        speed_rpm=problem.scenario.frame["speed_rpm"].to_numpy(), prior=prior)


def problem_kind(problem: Problem, channel: str) -> str:
    return next(c.kind for c in problem.channels if c.name == channel)


def _jitter(problem: Problem, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """σ of a start's jitter per search coordinate: :data:`JITTER_LOG` for log parameters, 10 % of the range
    (or of the value) for linear ones."""
    out = []
    for p, a, b in zip(problem.free, lo, hi):
        out.append(JITTER_LOG if p.log else 0.1 * (b - a if np.isfinite(b - a) else max(abs(p.value), 1.0)))
    return np.array(out)


def _full(problem: Problem, theta: np.ndarray) -> dict[str, Any]:
    """Linear parameters solved on the fit grid at θ, then predictions and RMSE on every sample."""
    sim = problem.simulate(theta)
    out = problem.outputs(sim)
    full = problem.outputs(problem.simulate(theta, full=True), out["linear"], full=True)
    pred = frame_of(problem, full["predictions"])
    rmse = {c.name: float(metrics.rmse(c.measured, pred[c.name].to_numpy())) for c in problem.channels}
    return {"sim_fit": sim, "out_fit": out, "linear": out["linear"], "predicted": pred, "rmse": rmse,
            "ridge": dict(problem.ridge)}


def with_linear(net: Network, linear: Mapping[str, Mapping[str, float]], problem: Problem) -> Network:
    """``net`` with the projected linear parameters written in (sensitivities, tilts, centrifugal, offsets)."""
    replaced = []
    for s in problem.temp_sensors:
        replaced.append(dataclasses.replace(s, offset_K=linear[s.name]["offset_K"]))
    for s in problem.disp_sensors:
        values = linear[s.name]
        out = net.output(s.output)
        sens = {k: values[k] for k in out.sensitivity_um_K} if out.sensitivity_um_K else {
            n: values[n] for n in net.node_names}
        tilt = {k: values[f"tilt:{k}"] for k in out.tilt_um_K}
        cf = values.get("centrifugal", 0.0)
        replaced.append(dataclasses.replace(out, sensitivity_um_K=sens, tilt_um_K=tilt, centrifugal_um=cf))
        replaced.append(dataclasses.replace(s, offset_um=values["offset_um"]))
    return net.replace(*replaced) if replaced else net
