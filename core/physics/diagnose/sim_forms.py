"""The regressors the simulation-given finder works with: recorded drivers, their first-order lags, and the
residual forms mechanisms declare for this mode.

A mechanism takes part in ``diagnose --simulation`` by declaring a class attribute ``simulation_form``, a dict::

    simulation_form = {"driver": "ambient",                # one of DRIVERS (below)
                       "taus_s": (1800.0, 7200.0, 28800.0),  # first-order lags tried (s); the fit picks one
                       "reaches": ("temperature", "displacement"),
                       "sign": 1,                          # sign of its effect on temperatures (0: either)
                       "axes": ("z",),                     # optional: only drift channels of these axes
                       "drift_sense": True}                # optional: the sign holds on drift channels too

``drift_sense``: a heat term on the spindle side moves the drift the way the spindle's own heat does, so its sign
holds on a drift channel times that channel's simulated sense (the sign of its simulated excess against the
hottest simulated temperature channel's, :func:`sense`). Without it the drift coefficient is free.

Drivers (each a series on the recording's times, zero at the start; ``r`` = speed / top speed; ``s_j`` the
simulated excess of channel j over its start; ``T̄`` the mean simulated temperature excess over ambient):

=================== ======================================================================================
ambient             recorded ambient (°C)
coolant_inlet       recorded coolant inlet (°C)
cutting_power       recorded cutting power (kW)
axis_velocity       |recorded axis velocity|^1.4 (in units of 10 m/min)
speed_power         r^p for each exponent in the form's ``exponents`` (heat that follows another law)
speed_squared       r² (a growth that follows speed itself, not heat)
speed_convection    −r^0.8 · (simulated excess over the air): cooling that grows with speed, on a temperature
                    channel of its own excess; on a drift channel two columns, the hottest simulated
                    temperature channel's (the rotating spindle, cooled most) and the mean's (the surfaces)
heat_feedback       r^1.5 · lag(r^1.5, 15 min): heat that grows with the heat already put in
slow_heat           lag(r^1.5, 1 h): heat through a further, slow store (the form's lags act on it)
bending             r^1.5 and its 4 h lag (the form's lags act on both; their difference is the band-pass of a
                    gradient across the structure, the far side catching up): a drift the spindle's heat drives
                    through a temperature difference across the structure, on a drift channel the simulation
                    does not move with that heat (a path the simulation lacks, not an error of one it has)
sensor_lag          a fixed form, not a regressor: each temperature channel read through a first-order lag
                    of the simulation plus its correction (the form's lags are the lags tried per channel)
=================== ======================================================================================

The calibration null (:func:`null_design`) is what imperfect parameters of the simulation produce: per channel
an offset, the simulated excess and two lags of it (gain and time-constant errors), lagged speed heat, and
lags of every recorded input the simulation responds to (as the user says, or :func:`detect_inputs`): that
input's path with a wrong gain or time constant. A mechanism driven by such an input is nested in the null:
it cannot be told from that path's error, and the finder says so instead of naming it. The speed-heat lags
stand only on the channels the simulation moves with the spindle's heat (:func:`responses`): an error in a
heat path's gain or lag scales or delays a response the simulation has, it does not create one. So the
mechanisms that change the spindle's heat paths (``HEAT_DRIVERS``) reach only those channels, and ``bending``
only the others.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thermodrift.core.physics.sensors import first_order_lag

INPUT_ROLES = ("ambient", "coolant_inlet", "cutting_power", "axis_velocity")
HEAT_DRIVERS = ("speed_power", "speed_convection", "heat_feedback", "slow_heat")  # change the spindle's heat paths
DRIVERS = (*INPUT_ROLES, *HEAT_DRIVERS, "speed_squared", "bending", "sensor_lag")
HEAT_EXPONENT = 1.5
BENDING_FAR_S = 14400.0                     # the far side of a bent structure follows its near side by this (s)
NULL_SIM_TAUS = (900.0, 3600.0)             # lags of the simulated excess in the null (s)
NULL_HEAT_TAUS = (300.0, 900.0, 3600.0, 10800.0, 36000.0)   # lags of speed heat in the null (s)
ID_TAUS = (300.0, 1800.0, 7200.0, 28800.0)  # lags an input's response is identified with (s)
NULL_INPUT_TAUS = (1800.0, 7200.0, 28800.0)  # lags of each input the simulation responds to, in the null (s)
ID_HEAT_TAUS = (300.0, 900.0, 3600.0, 10800.0, 36000.0)
IN_NULL = 0.01      # a form whose every lagged column, on every channel it reaches, leaves less than this share of
                    # its size outside the null's columns is nested in the null (:func:`outside`): the null takes
                    # it whole, so no held-out test can tell it from a parameter error of the simulation
RESPONDS = 0.01     # an input counts as driving the simulation when its lags explain 1 % of the channel's
                    # simulated range and half the channel's noise beyond what speed explains


@dataclass
class Inputs:
    """The recording's drivers on its times ``t`` (s): speed ratio r, and each recorded input (zero at start)."""

    t: np.ndarray
    r: np.ndarray
    inputs: dict[str, np.ndarray]

    @classmethod
    def of(cls, recording) -> "Inputs":
        t = recording.time_s
        speed = recording.speed.to_numpy(dtype=float).clip(min=0.0)
        top = float(speed.max()) if speed.max() > 0 else 1.0
        inputs = {}
        for role in INPUT_ROLES:
            cols = recording.columns(role)
            if not cols:
                continue
            x = recording.data[cols[0]].to_numpy(dtype=float)
            if np.ptp(x) <= 0:
                continue
            if role == "axis_velocity":
                x = (np.abs(x) / 10000.0) ** 1.4
            elif role == "cutting_power":
                x = x / 1000.0
            inputs[role] = x - x[0]
        return cls(t, speed / top, inputs)

    def lag(self, x: np.ndarray, tau_s: float) -> np.ndarray:
        return first_order_lag(x, self.t, tau_s)

    def heat(self) -> np.ndarray:
        return self.r ** HEAT_EXPONENT


def form_of(cls) -> dict | None:
    """A mechanism class's declared form for the simulation-given mode (None: it declares none)."""
    form = getattr(cls, "simulation_form", None)
    return dict(form) if form else None


def missing(form: dict, inputs: Inputs) -> str | None:
    """Why the recording cannot drive this form (a missing or constant input), else None."""
    d = form["driver"]
    if d not in DRIVERS:
        return f"its declared driver {d!r} is none of {', '.join(DRIVERS)}"
    if d in INPUT_ROLES and d not in inputs.inputs:
        return f"the recording has no varying {d} channel"
    if d not in INPUT_ROLES and d != "sensor_lag" and np.ptp(inputs.r) <= 0:
        return "the spindle speed is constant"
    return None


def drivers(form: dict, inputs: Inputs, sim_excess: np.ndarray, amb_excess: np.ndarray,
            local: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """The form's driver series before its lag (one per exponent for ``speed_power``); ``sim_excess`` the
    channel's simulated excess, ``amb_excess`` the mean simulated temperature excess over ambient, ``local``
    the excesses over the air a surface term acts on (°C; default ``amb_excess``)."""
    d = form["driver"]
    if d in INPUT_ROLES:  # ``shift_rows``: the recorded series circularly shifted (a specificity check)
        return [np.roll(inputs.inputs[d], int(form.get("shift_rows", 0)))]
    if d == "speed_power":
        return [inputs.r ** p for p in form.get("exponents", (0.75, 3.0))]
    if d == "speed_squared":
        return [inputs.r ** 2]
    if d == "speed_convection":
        return [-(inputs.r ** 0.8) * x for x in (local if local is not None else [amb_excess])]
    if d == "heat_feedback":
        h = inputs.heat()
        return [h * inputs.lag(h, 900.0)]
    if d == "slow_heat":
        return [inputs.lag(inputs.heat(), 3600.0)]
    if d == "bending":  # the difference across the structure rises with the heat, then the far side follows
        return [inputs.heat(), inputs.lag(inputs.heat(), BENDING_FAR_S)]
    raise ValueError(d)


def responses(inputs: Inputs, excess: np.ndarray, spans_sigma: np.ndarray) -> dict[str, np.ndarray]:
    """Which drivers the simulation responds to, per channel (role or ``speed`` → bool per channel): the
    simulated excess regressed on lagged powers of speed and lagged inputs; a driver counts on a channel when
    leaving its lags out raises the regression's RMS error (in quadrature) by :data:`RESPONDS` of the channel's
    simulated range and half its noise (speed: by half its noise)."""
    cols, owner = [np.ones_like(inputs.r)], ["offset"]
    for power in (1.0, HEAT_EXPONENT, 2.0):
        for tau in ID_HEAT_TAUS:
            cols.append(inputs.lag(inputs.r ** power, tau))
            owner.append("speed")
    for role, x in inputs.inputs.items():
        for tau in ID_TAUS:
            cols.append(inputs.lag(x, tau))
            owner.append(role)
    X = np.column_stack(cols)
    Xs = X / np.maximum(np.abs(X).max(axis=0), 1e-12)
    G = Xs.T @ Xs
    every = list(range(X.shape[1]))
    drivers = ["speed", *inputs.inputs]
    out = {d: np.zeros(excess.shape[1], dtype=bool) for d in drivers}
    for j in range(excess.shape[1]):
        y = excess[:, j]
        b, yy = Xs.T @ y, float(y @ y)

        def rms_left(keep: list[int]) -> float:
            beta = ridge_solve(G[np.ix_(keep, keep)], b[keep])
            return float(np.sqrt(max(yy - beta @ b[keep], 0.0) / len(y)))

        full = rms_left(every)
        for d in drivers:
            without = rms_left([i for i in every if owner[i] != d])
            # the spindle's heat counts wherever the noise would not hide it: a heat path with a wrong gain
            # moves a channel the simulation moves at all; so does the hall air, which does not follow the
            # programme (the floor keeps the speed's share from being read as an input that moves with it)
            floor = 0.0 if d in ("speed", "ambient") else RESPONDS * float(np.ptp(y))
            out[d][j] = np.sqrt(max(without ** 2 - full ** 2, 0.0)) > max(floor, 0.5 * spans_sigma[j])
    return out


def detect_inputs(found: dict[str, np.ndarray]) -> list[str]:
    """The recorded inputs the simulation responds to on any channel (``found``: :func:`responses`), read from its
    traces when the user does not say. Inputs that move with the speed (cutting while running) can be counted
    when they do not drive the simulation: the mechanisms they drive are then reported nested, never named
    wrongly."""
    return [r for r in INPUT_ROLES if r in found and found[r].any()]


def ridge_solve(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Normal equations G β = b of columns scaled to unit size, with a vanishing ridge (1e-9 of the mean
    diagonal) so that near-collinear lags (a simulated excess and its lags) stay solvable."""
    k = len(b)
    if k == 0:
        return np.zeros(0)
    lam = 1e-9 * float(np.trace(G)) / k + 1e-300
    return np.linalg.solve(G + lam * np.eye(k), b)


def heat_nested(form: dict) -> str:
    """Why a form reaches no channel the heat rule leaves it (a heat-path form reaches only the channels the
    simulation moves with the spindle's heat, a bending form only the others): the report's reason."""
    return "nested in the calibrated simulation: " + (
        "every channel it reaches already moves with the spindle's heat there, and a bending term cannot be told "
        "from that path with a wrong gain or lag" if form["driver"] == "bending" else
        "the simulation does not move the channels it reaches with the spindle's heat, and a change of a heat "
        "path cannot create that response")


def outside(X: np.ndarray, first: int, rows: np.ndarray) -> float:
    """The share of a form's columns (``X[:, first:]``, centred) that the null's columns (``X[:, :first]``)
    leave unexplained on ``rows`` (least squares, columns scaled to unit peak): below :data:`IN_NULL` the form
    is nested in the null."""
    Z, C = X[rows, :first], X[rows, first:]
    Z = Z / np.maximum(np.abs(Z).max(axis=0), 1e-12)
    left = C - Z @ np.linalg.lstsq(Z, C, rcond=None)[0]
    return float(np.sqrt((left ** 2).sum() / max(((C - C.mean(axis=0)) ** 2).sum(), 1e-300)))


def null_design(inputs: Inputs, sim_excess: np.ndarray, simulated: list[str], heated: bool = True) -> np.ndarray:
    """The calibration null's columns for one channel (see the module docstring); ``heated``: the simulation
    moves this channel with the spindle's heat (:func:`responses`), so its heat paths' errors reach it."""
    cols = [np.ones_like(sim_excess), sim_excess]
    cols += [inputs.lag(sim_excess, tau) for tau in NULL_SIM_TAUS]
    if heated:
        h = inputs.heat()
        cols += [inputs.lag(h, tau) for tau in NULL_HEAT_TAUS]
    for role in simulated:
        cols += [inputs.lag(inputs.inputs[role], tau) for tau in NULL_INPUT_TAUS]
    return np.column_stack(cols)


def hottest(excess: np.ndarray, kinds: list[str]) -> int | None:
    """The temperature channel with the largest simulated range (the spindle side), None without one."""
    temps = [k for k, kind in enumerate(kinds) if kind == "temperature"]
    return max(temps, key=lambda k: float(np.ptp(excess[:, k]))) if temps else None


def sense(excess: np.ndarray, kinds: list[str], j: int) -> int:
    """Channel ``j``'s simulated sense for the spindle's heat: +1 when its simulated excess rises with the
    hottest simulated temperature channel's, −1 when it falls (+1 without temperature channels)."""
    hot = hottest(excess, kinds)
    return 1 if hot is None or float(np.dot(excess[:, j], excess[:, hot])) >= 0 else -1


def surfaces(inputs: Inputs, excess: np.ndarray, kinds: list[str], j: int, amb_excess: np.ndarray):
    """The excesses over the air (°C) a surface term acts on for channel ``j``: a temperature channel's own; on
    a drift channel the hottest simulated temperature channel's (the spindle) and the mean of the surfaces."""
    air = inputs.inputs.get("ambient", np.zeros(len(excess)))
    if kinds[j] == "temperature":
        return [excess[:, j] - air]
    hot = hottest(excess, kinds)
    return [amb_excess] if hot is None else [excess[:, hot] - air, amb_excess]


def grid_interval(taus, tau: float) -> tuple[float, float]:
    """The lag's interval: from the lag tried below it to the one above (finite, containing the value)."""
    grid = sorted(taus)
    i = grid.index(tau)
    lo = grid[i - 1] if i > 0 else tau / 2
    hi = grid[i + 1] if i + 1 < len(grid) else tau * 2
    return float(lo), float(hi)


def gain_interval(X: np.ndarray, resid: np.ndarray, beta: np.ndarray, k: int, rows: np.ndarray):
    """95 % interval of coefficient ``k``: least-squares standard error, inflated for the residual's lag-1
    correlation (effective sample count n (1 − ρ) / (1 + ρ))."""
    r = resid[rows]
    rho = float(np.clip(np.dot(r[1:], r[:-1]) / max(np.dot(r, r), 1e-300), 0.0, 0.99))
    Xr = X[rows]
    scale = np.maximum(np.abs(Xr).max(axis=0), 1e-12)
    XtX = (Xr / scale).T @ (Xr / scale)
    var = float(np.linalg.pinv(XtX)[k, k]) / scale[k] ** 2 * float(np.mean(r ** 2)) * (1 + rho) / (1 - rho)
    half = 1.96 * np.sqrt(max(var, 0.0))
    return float(beta[k] - half), float(beta[k] + half)
