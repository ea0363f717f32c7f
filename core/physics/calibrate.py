"""Calibration of a thermal network to a recording by re-simulating the whole trajectory (grey-box output error).

The nonlinear parameters θ (conductances W/K, capacities J/K, heat-law amplitudes W and exponents) are searched
in log space with bounds by ``scipy.optimize.least_squares`` (trust-region reflective). For every θ the network
is simulated over the recording's inputs (speed, ambient, coolant, cutting power, axis velocity) and the
parameters that enter the outputs linearly are solved by linear least squares inside that step (variable
projection): per temperature channel its sensor offset (K), per displacement channel its sensitivities (µm/K,
tilt µm/K, centrifugal µm) and probe offset (µm). The objective is the sum over temperature and displacement
channels of squared residuals divided by each channel's noise σ, estimated from the data's high-frequency
residual (:func:`noise_sigma`), so °C and µm channels are fitted jointly on one scale.

Uncertainty: at the optimum the Jacobian J of the weighted, projected residual (central differences in log θ)
gives cov(log θ) = s² (JᵀJ)⁻¹ with s² = RSS/(n − p); intervals are log θ ± t·SE mapped back with exp, so they are
asymmetric and positive. The data cannot identify a parameter when its interval spans more than a factor
:data:`UNIDENTIFIABLE_RATIO`, or when it loads on a near-null singular direction of J (σ_j/σ_max <
:data:`NULL_TOLERANCE`); the direction is reported as the combination of log-parameters that the data leaves
free. The intervals assume white residuals: on real recordings model error is autocorrelated and they are
optimistic (the mismatch map says where the model is wrong).

The ``auto`` baseline network (:func:`auto_network`) is built from the recording's manifest alone. It assumes
exactly the following and nothing else (:data:`AUTO_ASSUMPTIONS`, also written into ``calibration.json`` —
the missing-physics finder starts from here):

1. One node per temperature channel (the sensor reads its node directly: no lag, a constant offset), plus
   ``hidden_nodes`` unobserved nodes (default 2) that act only on the displacements.
2. Every node has the same fixed heat capacity (1e4 J/K): temperatures identify only the ratios G/C and Q/C,
   so conductances and heat rates are estimated relative to that capacity.
3. Heat enters every node from the spindle speed alone: Q_i·(n/n_ref)^p with one exponent p shared by all nodes
   and n_ref the recording's top speed; no cutting, axis-drive, coolant or temperature-dependent heat.
   The hidden nodes' Q is fixed (their scale is absorbed by the sensitivities).
4. Each node loses heat by one constant conductance G_i to the ambient; no conduction between nodes, no
   speed-dependent convection, no radiation, no coolant.
5. Ambient is the recording's ambient channel when it has one (a measured boundary input), else a constant
   20 °C (a constant only shifts the sensor offsets, which are estimated anyway).
6. Displacement k = Σ_i s_ki (T_i − T_i,0) + b_k over all nodes: a linear, instantaneous expansion map; no
   centrifugal growth, no tilt terms, no lag.
7. The machine starts at rest in equilibrium with the ambient.

Free parameters of the auto network: G_i of every node and p (nonlinear), and Q_i ≥ 0 of every temperature
node — its node is read by one sensor and touches only the ambient, so the reading is linear in Q_i and Q_i is
projected out with the offset (start values for all of them come from each channel's first warm-up). For a
user network the default free set is every positive capacity, conductance, advection and heat-source amplitude
(:func:`default_free`); exponents stay fixed unless named.

The search simulates and compares on a grid of at most :data:`MAX_FIT_SAMPLES` samples (every k-th sample,
inputs held from it); the final predictions, RMSEs and the mismatch map use every sample.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import math
import re
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import pandas as pd
from scipy import optimize, stats
from threadpoolctl import ThreadpoolController

from thermodrift.core.errors import InputError
from thermodrift.core.physics.integrate import CompiledNetwork
from thermodrift.core.physics.network import (BOUNDARIES, BearingSource, DisplacementSensor, Edge, Network, Node,
                                              Output, TemperatureSensor)
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.physics.sensors import first_order_lag

AUTO_CAPACITY_J_K = 1.0e4
AUTO_AMBIENT_DEGC = 20.0
UNIDENTIFIABLE_RATIO = 10.0  # hi/lo of the interval beyond which a parameter counts as not identified
NULL_TOLERANCE = 1e-4        # σ_j/σ_max of J below which a singular direction counts as unidentifiable
# Small dense algebra (≤ 20 nodes) is fastest single-threaded; a BLAS pool on a busy machine made lstsq 7× slower.
_THREADS = ThreadpoolController()
MAX_FIT_SAMPLES = 2500       # the search simulates and compares on a grid of at most this many samples

AUTO_ASSUMPTIONS = (
    "one node per temperature channel (read directly: no sensor lag, constant offset) plus hidden nodes that "
    "act only on the displacements",
    f"every node has the same fixed capacity {AUTO_CAPACITY_J_K:g} J/K; G and Q are relative to it",
    "heat from spindle speed only: Q_i (n/n_ref)^p, one exponent p for all nodes, n_ref = top speed of the "
    "recording; no cutting, axis-drive, coolant or temperature-dependent heat",
    "one constant conductance per node to ambient; no conduction between nodes, no speed-dependent "
    "convection, no radiation, no coolant",
    f"ambient = the recording's ambient channel if present, else constant {AUTO_AMBIENT_DEGC:g} degC",
    "displacement = sum_i s_ki (T_i - T_i0) + b_k over all nodes: linear, instantaneous; no centrifugal "
    "growth, no tilt, no lag",
    "starts at rest in equilibrium with the ambient",
)

# Fields that the default free set takes when positive (amplitudes and conductances, not exponents).
_DEFAULT_FREE_FIELDS = ("capacity_J_K", "G_W_K", "G_rot_W_K", "mdot_cp_W_K", "viscous_W", "load_W", "no_load_W",
                        "power_W", "fraction", "gain_W_K")


# --- free parameters -------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FreeParameter:
    """A positive network parameter searched in log space; ``paths`` tied to one value (dotted, see
    :meth:`Network.parameters`)."""

    name: str
    paths: tuple[str, ...]
    value: float
    low: float
    high: float
    unit: str = ""
    projected_by: str | None = None  # temperature channel whose reading this heat amplitude scales linearly

    def __post_init__(self):
        if not 0 < self.low <= self.value <= self.high:
            raise InputError(f"free parameter {self.name!r}: need 0 < low ≤ value ≤ high, got "
                             f"{self.low:g} ≤ {self.value:g} ≤ {self.high:g}")


def _unit_of(path: str) -> str:
    for suffix, unit in (("_J_K", "J/K"), ("_W_K", "W/K"), ("_W", "W"), ("exponent", "1"), ("fraction", "1")):
        if path.endswith(suffix):
            return unit
    return ""


def free_from_paths(network: Network, patterns: Sequence[str], spread: float = 100.0) -> list[FreeParameter]:
    """Free parameters for every positive network parameter whose path matches one of ``patterns`` (globs),
    bounded to [value/spread, value·spread] (exponents: [0.3, 3])."""
    values = network.parameters()
    out = []
    for path, v in values.items():
        if any(fnmatch.fnmatchcase(path, p) for p in patterns):
            if v <= 0:
                raise InputError(f"free parameter {path!r} is {v:g}; only positive parameters can be calibrated "
                                 "in log space", hint="give it a positive start value in the network spec")
            low, high = (0.3, 3.0) if path.endswith("exponent") else (v / spread, v * spread)
            out.append(FreeParameter(path, (path,), v, min(low, v), max(high, v), _unit_of(path)))
    missing = [p for p in patterns if not any(fnmatch.fnmatchcase(path, p) for path in values)]
    if missing:
        raise InputError(f"free parameter pattern(s) {missing} match nothing in network {network.name!r}",
                         hint="paths look like edges.<edge>.G_W_K or nodes.<node>.capacity_J_K")
    return out


def default_free(network: Network) -> list[FreeParameter]:
    """Every positive capacity, conductance, advection and heat-source amplitude of ``network``."""
    paths = [p for p, v in network.parameters().items()
             if p.split(".")[0] in ("nodes", "edges", "advections", "sources")
             and p.split(".")[-1] in _DEFAULT_FREE_FIELDS and v > 0]
    return free_from_paths(network, paths)


# --- the auto baseline -------------------------------------------------------------------------------------------

@dataclass
class AutoBaseline:
    """The ``auto`` network of a recording, its free parameters and what it assumes."""

    network: Network
    free: list[FreeParameter]
    assumptions: tuple[str, ...] = AUTO_ASSUMPTIONS
    channel_nodes: dict[str, str] = field(default_factory=dict)  # temperature column -> node


def _safe(name: str) -> str:
    return re.sub(r"[^0-9A-Za-z_]+", "_", str(name)).strip("_") or "ch"


def _unique(names: list[str], base: str) -> str:
    name, i = base, 2
    while name in names or name in BOUNDARIES:
        name, i = f"{base}_{i}", i + 1
    names.append(name)
    return name


def run_segments(speed_rpm: np.ndarray, tol_rpm: float = 25.0) -> list[tuple[int, int, float]]:
    """(start, stop, level rpm) of each constant-speed stretch of a piecewise-constant schedule."""
    v = np.asarray(speed_rpm, dtype=float)
    change = np.flatnonzero(np.abs(np.diff(v)) > tol_rpm) + 1
    starts, stops = np.r_[0, change], np.r_[change, len(v)]
    return [(int(a), int(b), float(np.median(v[a:b]))) for a, b in zip(starts, stops)]


def step_response_start(time_s: np.ndarray, temperature: np.ndarray, speed_rpm: np.ndarray,
                        n_ref: float, exponent: float) -> tuple[float, float]:
    """Start values (time constant s, heat per capacity at n_ref K/s) read off the first warm-up of a channel.

    The rise over the first run is T(t) − T(start); its end value K is the steady rise (the run is taken as
    long enough), τ the time to 63 % of K. Heat at n_ref: K/τ·(n_ref/n)^p per unit capacity.
    """
    runs = [s for s in run_segments(speed_rpm) if s[2] > 0]
    default_tau = 3600.0
    if not runs:
        return default_tau, 1e-6
    a, b, level = max(runs[:3], key=lambda s: s[1] - s[0]) if len(runs) > 1 else runs[0]
    rise = temperature[a:b] - temperature[a]
    tail = max(1, (b - a) // 20)
    final = float(np.mean(rise[-tail:]))
    if final <= 0 or b - a < 4:
        return default_tau, 1e-6
    reached = np.flatnonzero(rise >= 0.632 * final)
    tau = float(time_s[a + reached[0]] - time_s[a]) if len(reached) else float(time_s[b - 1] - time_s[a])
    tau = min(max(tau, 60.0), 20 * 3600.0)
    return tau, final / tau * (n_ref / level) ** exponent


def auto_network(recording, hidden_nodes: int = 2, capacity_J_K: float = AUTO_CAPACITY_J_K,
                 heat_exponent: float = 1.5) -> AutoBaseline:
    """The baseline network of ``recording`` from its manifest alone (see the module docstring).

    Start values come from each temperature channel's first warm-up (:func:`step_response_start`); hidden
    nodes start with time constants log-spaced over 0.5–4 h. Node groups are guesses for the mechanism library:
    temperature nodes rising ≥ 50 % of the largest rise are ``bearing``, ≥ 10 % ``housing``, else ``structure``;
    hidden nodes are ``shaft``.
    """
    speed = recording.speed
    if speed is None or not (speed.to_numpy() > 0).any():
        raise InputError(f"{recording.source}: the auto network needs a speed channel with the spindle running",
                         hint="give the speed column role 'speed' in the manifest, or pass --network spec.yaml")
    temps = recording.temperatures
    disps = recording.displacements
    if temps.shape[1] == 0 and hidden_nodes == 0:
        raise InputError(f"{recording.source}: no temperature channel and no hidden node to build a network from")
    t, n = recording.time_s, speed.to_numpy(dtype=float)
    n_ref = float(n.max())
    names: list[str] = []
    nodes, edges, sources, sensors, free = [], [], [], [], []
    channel_nodes: dict[str, str] = {}
    starts = {c: step_response_start(t, temps[c].to_numpy(dtype=float), n, n_ref, heat_exponent) for c in temps}
    gains = {c: q * tau for c, (tau, q) in starts.items()}
    top = max(gains.values(), default=0.0)
    g_bounds = (capacity_J_K / (40 * 24 * 3600.0), capacity_J_K / 30.0)  # τ from 30 s to 40 days
    q_bounds = (1e-6 * capacity_J_K / 3600.0, 1e3 * capacity_J_K / 60.0)  # up to 1000 K rise per minute

    def add_node(base: str, group: str, tau: float, q_per_c: float, heat_free: str | None) -> str:
        node = _unique(names, base)
        g = capacity_J_K / tau
        q = min(max(q_per_c * capacity_J_K, q_bounds[0]), q_bounds[1])
        nodes.append(Node(node, capacity_J_K, group))
        edges.append(Edge(f"{node}-ambient", node, "ambient", g, kind="convection"))
        sources.append(BearingSource(f"heat_{node}", node, viscous_W=q, viscous_exponent=heat_exponent))
        free.append(FreeParameter(f"G[{node}]", (f"edges.{node}-ambient.G_W_K",), g, *g_bounds, "W/K"))
        if heat_free:
            # The node is read by one sensor and touches only the ambient, so its reading is linear in Q.
            free.append(FreeParameter(f"Q[{node}]", (f"sources.heat_{node}.viscous_W",), q, *q_bounds, "W",
                                      projected_by=heat_free))
        return node

    for c in temps:
        tau, q = starts[c]
        share = gains[c] / top if top > 0 else 0.0
        group = "bearing" if share >= 0.5 else "housing" if share >= 0.1 else "structure"
        node = add_node(_safe(c), group, tau, q, heat_free=c)
        channel_nodes[c] = node
        sensors.append(TemperatureSensor(c, node, noise_K=0.0, location=str(recording.channels[c].meta.get(
            "location", ""))))
    for k, tau in enumerate(np.geomspace(0.5, 4.0, hidden_nodes) * 3600.0 if hidden_nodes > 1 else
                            [1.5 * 3600.0] * hidden_nodes):
        add_node(f"hidden_{k + 1}", "shaft", float(tau), 1.0 / float(tau), heat_free=None)
    free.append(FreeParameter("heat_exponent", tuple(f"sources.{s.name}.viscous_exponent" for s in sources),
                              heat_exponent, 0.3, 3.0, "1"))
    outputs = []
    for c in disps:
        out = _unique(names, _safe(c))
        axis = str(recording.channels[c].meta.get("axis", "unknown"))
        outputs.append(Output(out, axis=axis, sensitivity_um_K={nd.name: 0.0 for nd in nodes}))
        sensors.append(DisplacementSensor(c, out, noise_um=0.0))
    ambient = recording.columns("ambient")
    desc = (f"auto baseline of {recording.source}: {temps.shape[1]} temperature nodes, {hidden_nodes} hidden, "
            f"ambient {'channel ' + repr(ambient[0]) if ambient else f'constant {AUTO_AMBIENT_DEGC:g} degC'}")
    net = Network("auto", tuple(nodes), tuple(edges), (), tuple(sources), tuple(outputs), tuple(sensors),
                  reference_speed_rpm=n_ref, description=desc).validate()
    return AutoBaseline(net, free, AUTO_ASSUMPTIONS, channel_nodes)


# --- fast trajectory ----------------------------------------------------------------------------------------------

@dataclass
class ScenarioArrays:
    """The numeric signals of a :class:`Scenario` read once (column access on the scenario's frame, which also
    holds the condition labels, costs more than a whole small simulation)."""

    frame: pd.DataFrame  # the numeric signal columns only; what CompiledNetwork.inputs reads
    time_s: np.ndarray
    speed_rpm: np.ndarray
    coolant_flow: np.ndarray

    @classmethod
    def of(cls, scenario: Scenario) -> "ScenarioArrays":
        f = scenario.frame.drop(columns="condition")
        return cls(f, scenario.time_s, f["speed_rpm"].to_numpy(), f["coolant_flow"].to_numpy())


def trajectory(comp: CompiledNetwork, scenario: Scenario | ScenarioArrays,
               initial: np.ndarray | None = None) -> np.ndarray:
    """Node temperatures (°C, K × N) of ``comp`` over ``scenario``, exact for zero-order-hold inputs.

    Same result as :func:`thermodrift.core.physics.simulate` (same Φ, Γ per level) but the recursion
    x_{k+1} = Φ x_k + Γ u_k runs in the modal coordinates of Φ, one vectorised first-order filter per mode,
    instead of a Python loop over steps — the calibration re-simulates hundreds of times. ``initial`` defaults to
    equilibrium at rest with the first sample's boundaries.
    """
    from scipy.signal import lfilter  # imported here: ~1 s, not to be paid when plugins load

    arrays = scenario if isinstance(scenario, ScenarioArrays) else ScenarioArrays.of(scenario)
    with _THREADS.limit(limits=1, user_api="blas"):
        t, speed, flow = arrays.time_s, arrays.speed_rpm, arrays.coolant_flow
        U = comp.inputs(arrays)
        N = len(comp.names)
        X = np.empty((len(t), N))
        if initial is None:
            rest = U[0].copy()
            rest[1 + len(BOUNDARIES):] = 0.0
            initial = comp.steady_state(0.0, flow[0], rest)
        x = X[0] = np.asarray(initial, dtype=float)
        dt = np.round(np.diff(t), 9)
        keys = np.column_stack([speed[:-1], flow[:-1], dt])
        change = np.flatnonzero(np.any(keys[1:] != keys[:-1], axis=1)) + 1
        modes: dict[tuple, tuple] = {}
        for a, b in zip(np.r_[0, change], np.r_[change, len(t) - 1]):
            key = (float(speed[a]), float(flow[a]), float(dt[a]))
            Phi, Gam = comp.step(*key, "exact")
            if key not in modes:
                d, V = np.linalg.eig(Phi)
                if np.abs(d.imag).max() < 1e-12 and np.abs(V.imag).max() < 1e-12:  # symmetrizable: real modes
                    d, V = d.real, V.real
                modes[key] = (d, V, np.linalg.inv(V)) if np.linalg.cond(V) < 1e8 else None
            W = U[a:b] @ Gam.T
            if modes[key] is None:  # nearly defective Φ (strong advection): plain recursion
                for k in range(b - a):
                    x = Phi @ x + W[k]
                    X[a + k + 1] = x
                continue
            d, V, Vi = modes[key]
            Wz, z0 = W @ Vi.T, Vi @ x
            Z = np.empty_like(Wz)
            if np.ptp(W, axis=0).max(initial=0.0) == 0.0:  # constant inputs: closed form
                k = np.arange(1, b - a + 1)[:, None]
                dk = d[None, :] ** k
                one = np.abs(1 - d) < 1e-14
                geo = np.where(one, k, (1 - dk) / np.where(one, 1.0, 1 - d))
                Z = dk * z0 + geo * Wz[0]
            else:
                for j in range(N):
                    Z[:, j] = lfilter([1.0], [1.0, -d[j]], Wz[:, j], zi=[d[j] * z0[j]])[0]
            Xs = Z @ V.T
            X[a + 1:b + 1] = Xs.real
            x = X[b]
    return X


# --- the calibration problem -------------------------------------------------------------------------------------

def noise_sigma(values: np.ndarray) -> float:
    """Noise σ of a channel from its high-frequency residual: MAD of second differences / √6 (robust to the
    signal's own curvature and to speed-step jumps); std when quantization makes the MAD zero; floored at
    1e-6 of the channel's range so a flat channel cannot take an infinite weight."""
    x = np.asarray(values, dtype=float)
    d2 = np.diff(x, 2)
    if len(d2) < 3:
        return max(float(np.ptp(x)) * 1e-3, 1e-9)
    s = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)
    if s == 0.0:
        s = float(np.std(d2)) / math.sqrt(6.0)
    return max(s, 1e-6 * float(np.ptp(x)), 1e-9)


@dataclass
class _Channel:
    name: str
    kind: str            # "temperature" | "displacement"
    unit: str
    sigma: float
    measured: np.ndarray


@dataclass
class _Sim:
    """One simulation: the network, node temperatures X (°C) and their response to the boundaries alone."""

    net: Network
    X: np.ndarray
    X_boundary: np.ndarray


class _Problem:
    """Maps θ → weighted, projected residuals for one recording (see the module docstring).

    Heat amplitudes with ``projected_by`` set are linear too: their node is read by one sensor and exchanges heat
    only with the ambient, so the reading is boundary response + Q·(response to 1 W). The search simulates them
    at 1 W and solves Q ≥ 0 with the channel's offset; the displacements then see the scaled node temperatures.
    """

    def __init__(self, network: Network, free: list[FreeParameter], recording, targets: Sequence[str] | None,
                 max_fit_samples: int):
        self.network = network
        self.free = [p for p in free if p.projected_by is None]
        self.projected = {p.projected_by: p for p in free if p.projected_by is not None}
        self.scenario = Scenario.from_recording(recording, ambient_degC=AUTO_AMBIENT_DEGC)
        self.time_s = recording.time_s
        self.speed_ratio = self.scenario.frame["speed_rpm"].to_numpy() / network.reference_speed_rpm
        data = recording.data
        disp_cols = set(recording.columns("displacement"))
        if targets:
            unknown = [c for c in targets if c not in disp_cols]
            if unknown:
                raise InputError(f"targets {unknown} are not displacement channels of {recording.source}",
                                 hint=f"choose from {sorted(disp_cols)}")
        temp_cols = {c for r in ("temperature", "ambient", "coolant_inlet", "coolant_outlet")
                     for c in recording.columns(r)}
        self.temp_sensors = [s for s in network.temperature_sensors if s.name in temp_cols]
        self.disp_sensors = [s for s in network.displacement_sensors if s.name in disp_cols
                             and (not targets or s.name in targets)]
        if not self.temp_sensors and not self.disp_sensors:
            raise InputError(f"no sensor of network {network.name!r} matches a channel of {recording.source}",
                             hint="sensor names in the spec must equal the recording's column names")
        self.channels = [_Channel(s.name, "temperature", "K", noise_sigma(data[s.name]), data[s.name].to_numpy(float))
                         for s in self.temp_sensors]
        self.channels += [_Channel(s.name, "displacement", "um", noise_sigma(data[s.name]),
                                   data[s.name].to_numpy(float)) for s in self.disp_sensors]
        self.measured = {c.name: c.measured for c in self.channels}
        stride = max(1, math.ceil(len(self.time_s) / max_fit_samples))
        self.rows = np.arange(0, len(self.time_s), stride)
        # The search simulates on the fit grid (inputs held from each grid sample; exact for the held inputs),
        # final predictions use the full grid.
        fit_scenario = Scenario(self.scenario.frame.iloc[self.rows], self.scenario.name)
        self.arrays = {False: ScenarioArrays.of(fit_scenario), True: ScenarioArrays.of(self.scenario)}
        self.resting = {full: ScenarioArrays.of(Scenario(scen.frame.assign(
            speed_rpm=0.0, cutting_power_W=0.0, axis_velocity_mm_min=0.0), scen.name))
            for full, scen in ((False, fit_scenario), (True, self.scenario))}
        self.boundaries = {"ambient": self.scenario.frame["ambient_degC"].to_numpy(),
                           "coolant": self.scenario.frame["coolant_inlet_degC"].to_numpy()}
        self.constant_boundaries = all(np.ptp(v) == 0 for v in self.boundaries.values())
        self.n_linear = (len(self.temp_sensors) + len(self.projected)
                         + sum(len(self._regressor_names(s)) + 1 for s in self.disp_sensors))
        self.best: tuple[float, np.ndarray] | None = None
        self.evaluations = 0

    # θ (log) <-> network
    @property
    def theta0(self) -> np.ndarray:
        return np.log([p.value for p in self.free])

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.log([p.low for p in self.free]), np.log([p.high for p in self.free])

    def network_at(self, theta: np.ndarray, heat: Mapping[str, float] | None = None) -> Network:
        """The network at θ with projected heat amplitudes at ``heat`` (default 1 W each, the unit response)."""
        values = {path: float(np.exp(v)) for p, v in zip(self.free, theta) for path in p.paths}
        values.update({path: (heat or {}).get(p.name, 1.0) for p in self.projected.values() for path in p.paths})
        return _set_values(self.network, values)

    def _regressor_names(self, sensor: DisplacementSensor) -> list[str]:
        out = self.network.output(sensor.output)
        names = list(out.sensitivity_um_K) or self.network.node_names
        names += [f"tilt:{h}/{c}" for h, c, _ in out.tilt_pairs()]
        return names + (["centrifugal"] if out.centrifugal_um else [])

    # simulation and projection
    def simulate(self, theta: np.ndarray, full: bool = False) -> _Sim:
        """The network at θ and its node temperatures on the fit grid (or the full grid)."""
        net = self.network_at(theta)
        comp = CompiledNetwork(net)
        X = trajectory(comp, self.arrays[full])
        if not self.projected:
            Xb = X
        elif self.constant_boundaries:  # at rest in equilibrium with constant boundaries
            Xb = np.broadcast_to(X[0], X.shape)
        else:
            Xb = trajectory(comp, self.resting[full])
        return _Sim(net, X, Xb)

    def outputs(self, sim: _Sim, linear: Mapping[str, Mapping[str, float]] | None = None,
                full: bool = False) -> dict[str, Any]:
        """Predicted channels on the fit grid with the linear parameters solved there (``linear`` None), or on
        the grid of the simulation with the given linear parameters."""
        net, X = sim.net, sim.X.copy()
        idx = {n: i for i, n in enumerate(net.node_names)}
        grid = slice(None) if full else self.rows
        time_s, ratio = self.time_s[grid], self.speed_ratio[grid]
        solve = linear is None
        preds: dict[str, np.ndarray] = {}
        linear = {} if solve else {k: dict(v) for k, v in linear.items()}

        def reading(s: TemperatureSensor, nodes: np.ndarray) -> np.ndarray:
            v = sum(w * (nodes[:, idx[n]] if n in idx else self.boundaries[n][grid]) for n, w in s.weights.items())
            return first_order_lag(v, time_s, s.lag_s) if s.lag_s > 0 else v

        for s in self.temp_sensors:
            base = reading(s, X)
            proj = self.projected.get(s.name)
            if proj is not None:
                node = idx[next(iter(s.weights))]
                base_b = reading(s, sim.X_boundary)
                phi = base - base_b
                if solve:
                    meas = self.measured[s.name][grid]
                    A = np.column_stack([phi, np.ones(len(phi))])
                    q, off = np.linalg.lstsq(A, meas - base_b, rcond=None)[0]
                    if q < 0:  # heat cannot be negative: the channel does not warm with speed
                        q, off = 0.0, float(np.mean(meas - base_b))
                    linear[s.name] = {"offset_K": float(off), proj.name: float(q)}
                q = linear[s.name][proj.name]
                X[:, node] = sim.X_boundary[:, node] + q * (sim.X[:, node] - sim.X_boundary[:, node])
                base = base_b + q * phi
            elif solve:
                linear[s.name] = {"offset_K": float(np.mean(self.measured[s.name][grid] - base))}
            preds[s.name] = base + linear[s.name]["offset_K"]
        groups: dict[tuple[str, ...], list[DisplacementSensor]] = {}
        for s in self.disp_sensors:  # channels sharing regressors are solved in one lstsq
            groups.setdefault(tuple(self._regressor_names(s)), []).append(s)
        for names, sensors in groups.items():
            cols = []
            for name in names:
                if name == "centrifugal":
                    cols.append(ratio ** 2)
                elif name.startswith("tilt:"):
                    h, c = name[5:].split("/", 1)
                    cols.append((X[:, idx[h]] - X[0, idx[h]]) - (X[:, idx[c]] - X[0, idx[c]]))
                else:
                    cols.append(X[:, idx[name]] - X[0, idx[name]])
            A = np.column_stack(cols + [np.ones(len(X))])
            if solve:
                scale = np.maximum(np.abs(A).max(axis=0), 1e-12)  # column scaling for a well-posed lstsq
                Y = np.column_stack([self.measured[s.name][grid] for s in sensors])
                beta = np.linalg.lstsq(A / scale, Y, rcond=1e-10)[0] / scale[:, None]
                for j, s in enumerate(sensors):
                    linear[s.name] = {**{n: float(v) for n, v in zip(names, beta[:-1, j])},
                                      "offset_um": float(beta[-1, j])}
            for s in sensors:
                preds[s.name] = A @ np.array([linear[s.name][n] for n in names] + [linear[s.name]["offset_um"]])
        return {"predictions": preds, "linear": linear}

    def heat(self, linear: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        """Projected heat amplitudes (W) from solved linear parameters."""
        return {p.name: linear[ch][p.name] for ch, p in self.projected.items() if ch in linear}

    def weighted(self, preds: Mapping[str, np.ndarray]) -> np.ndarray:
        """Residuals on the fit grid divided by each channel's noise σ, channels one after another."""
        return np.concatenate([(c.measured[self.rows] - preds[c.name]) / c.sigma for c in self.channels])

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        r = self.weighted(self.outputs(self.simulate(theta))["predictions"])
        self.evaluations += 1
        cost = float(r @ r)
        if not np.isfinite(cost):
            return np.full_like(r, 1e6)
        if self.best is None or cost < self.best[0]:
            self.best = (cost, np.array(theta, dtype=float))
        return r


def _set_values(network: Network, values: Mapping[str, float]) -> Network:
    """``network.with_values(values)`` with one replacement per element (the search calls it per evaluation)."""
    changes: dict[tuple[str, str], dict[str, Any]] = {}
    for path, v in values.items():
        coll, name, fname, *key = path.split(".", 3)
        fields = changes.setdefault((coll, name), {})
        if key:
            fields[fname] = {**fields.get(fname, getattr(_element(network, coll, name, path), fname)), key[0]: v}
        else:
            fields[fname] = v
    colls = {}
    for (coll, name), fields in changes.items():
        items = colls.setdefault(coll, list(getattr(network, coll)))
        i = next(i for i, e in enumerate(items) if e.name == name)
        items[i] = dataclasses.replace(items[i], **fields)
    return dataclasses.replace(network, **{c: tuple(v) for c, v in colls.items()})


def _element(network: Network, coll: str, name: str, path: str) -> Any:
    for e in getattr(network, coll):
        if e.name == name:
            return e
    raise InputError(f"unknown parameter {path!r} in network {network.name!r}")


class _OutOfTime(Exception):
    pass


# --- results ---------------------------------------------------------------------------------------------------

@dataclass
class Estimate:
    """A calibrated nonlinear parameter with its confidence interval (same unit)."""

    name: str
    paths: tuple[str, ...]
    value: float
    start: float
    low: float
    high: float
    se_log: float
    at_bound: bool
    unit: str

    @property
    def ratio(self) -> float:
        """hi/lo of the interval (1: exact; ≥ UNIDENTIFIABLE_RATIO: not identified; nan: not computed)."""
        if math.isnan(self.low):
            return math.nan
        return self.high / self.low if self.low > 0 else math.inf


@dataclass
class CalibrationResult:
    """Everything a calibration found; :meth:`to_dict` is what ``calibration.json`` holds."""

    network_initial: Network
    network: Network
    estimates: list[Estimate]
    linear: dict[str, dict[str, float]]            # channel -> offset / sensitivities
    sigma: dict[str, float]                        # channel -> noise σ used as weight (K or µm)
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
    stopped: str
    assumptions: tuple[str, ...] = ()
    time_s: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False)
    measured: pd.DataFrame | None = field(default=None, repr=False)
    predicted_initial: pd.DataFrame | None = field(default=None, repr=False)
    predicted: pd.DataFrame | None = field(default=None, repr=False)
    channel_kind: dict[str, str] = field(default_factory=dict)
    speed_rpm: np.ndarray | None = field(default=None, repr=False)

    @property
    def residuals(self) -> pd.DataFrame:
        """Measured minus calibrated prediction (K, µm) per channel."""
        return self.measured - self.predicted

    def estimate(self, name: str) -> Estimate:
        return next(e for e in self.estimates if e.name == name)

    def to_dict(self) -> dict[str, Any]:
        return {
            "network": self.network.name,
            "description": self.network.description,
            "assumptions": list(self.assumptions),
            "confidence_level": self.level,
            "estimates": {e.name: {"value": e.value, "ci": [_num(e.low), _num(e.high)], "start": e.start,
                                   "unit": e.unit, "se_log": _num(e.se_log), "ci_ratio": _num(e.ratio),
                                   "at_bound": e.at_bound,
                                   "paths": list(e.paths)} for e in self.estimates},
            "linear": self.linear,
            "unidentifiable": self.unidentifiable,
            "null_directions": self.null_directions,
            "noise_sigma": self.sigma,
            "rmse_initial": self.rmse_initial,
            "rmse": self.rmse,
            "objective": {"initial": self.cost_initial, "final": self.cost, "s2": self.s2,
                          "evaluations": self.evaluations, "seconds": round(self.seconds, 3),
                          "stopped": self.stopped},
        }


def _num(x: float) -> float | None:
    """JSON-safe number: None for an infinite or undefined value."""
    return float(x) if math.isfinite(x) else None


def _jacobian(fun: Callable[[np.ndarray], np.ndarray], theta: np.ndarray, lo: np.ndarray, hi: np.ndarray,
              h: float = 1e-3) -> np.ndarray:
    """Central differences in log θ (one-sided at a bound)."""
    cols = []
    for i in range(len(theta)):
        up, dn = theta.copy(), theta.copy()
        up[i] = min(theta[i] + h, hi[i])
        dn[i] = max(theta[i] - h, lo[i])
        cols.append((fun(up) - fun(dn)) / (up[i] - dn[i]))
    return np.column_stack(cols) if cols else np.empty((0, 0))


def calibrate(recording, network: Network | None = None, *, free: Sequence[FreeParameter] | Sequence[str] | None = None,
              targets: Sequence[str] | None = None, hidden_nodes: int = 2, max_seconds: float | None = None,
              max_evaluations: int | None = None, level: float = 0.95, max_fit_samples: int = MAX_FIT_SAMPLES,
              intervals: bool = True, progress: bool = False) -> CalibrationResult:
    """Calibrate ``network`` (None: :func:`auto_network` of the recording) to ``recording``.

    ``free``: FreeParameter objects, or glob patterns over parameter paths (default: the auto network's own set,
    else :func:`default_free`). ``targets``: displacement channels to fit (default all that a sensor reads).
    ``max_seconds`` stops the search and keeps the best point found; ``level`` is the interval confidence;
    ``intervals=False`` skips the final Jacobian (estimates without intervals or identifiability, for fitting a
    model many times).
    """
    with _THREADS.limit(limits=1, user_api="blas"):
        return _calibrate(recording, network, free, targets, hidden_nodes, max_seconds, max_evaluations, level,
                          max_fit_samples, intervals, progress)


def _calibrate(recording, network, free, targets, hidden_nodes, max_seconds, max_evaluations, level,
               max_fit_samples, intervals, progress) -> CalibrationResult:
    start_clock = time.perf_counter()
    assumptions: tuple[str, ...] = ()
    if network is None:
        auto = auto_network(recording, hidden_nodes=hidden_nodes)
        network, default = auto.network, auto.free
        assumptions = auto.assumptions
    else:
        default = None
    if free is None:
        free = default if default is not None else default_free(network)
    elif free and isinstance(free[0], str):
        free = free_from_paths(network, list(free))
    free = list(free)
    problem = _Problem(network, free, recording, targets, max_fit_samples)
    lo, hi = problem.bounds
    theta0 = np.clip(problem.theta0, lo, hi)
    r0 = problem.residuals(theta0)
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(desc="calibrate", unit="sim", leave=False)

    def fun(theta: np.ndarray) -> np.ndarray:
        if max_seconds is not None and time.perf_counter() - start_clock > max_seconds:
            raise _OutOfTime
        r = problem.residuals(theta)
        if bar is not None:
            bar.update()
            bar.set_postfix(cost=f"{problem.best[0]:.4g}")
        return r

    stopped = "no nonlinear parameters"
    if problem.free:
        try:
            # diff_step: forward differences of 1e-4 in log θ stay well above the simulation's round-off.
            sol = optimize.least_squares(fun, theta0, bounds=(lo, hi), x_scale=1.0, method="trf",
                                         max_nfev=max_evaluations, xtol=1e-10, ftol=1e-8, diff_step=1e-4)
            stopped = sol.message
        except _OutOfTime:
            stopped = f"time limit of {max_seconds:g} s reached; best point kept"
    theta = problem.best[1] if problem.best is not None else theta0
    sim = problem.simulate(theta)
    out = problem.outputs(sim)
    r = problem.weighted(out["predictions"])
    dof = max(len(r) - len(problem.free) - problem.n_linear, 1)
    s2 = float(r @ r) / dof
    if intervals:
        J = _jacobian(problem.residuals, theta, lo, hi) if problem.free else np.zeros((len(r), 0))
        estimates, unidentifiable, null_dirs = _uncertainty(problem, theta, J, s2, dof, level, lo, hi, sim, out)
    else:
        estimates = [Estimate(p.name, p.paths, float(np.exp(v)), p.value, math.nan, math.nan, math.nan,
                              False, p.unit) for p, v in zip(problem.free, theta)]
        estimates += [Estimate(p.name, p.paths, out["linear"][ch][p.name], p.value, math.nan, math.nan, math.nan,
                               False, p.unit) for ch, p in problem.projected.items()]
        unidentifiable, null_dirs = [], []
    if bar is not None:
        bar.close()
    sim0 = problem.simulate(theta0)
    out0 = problem.outputs(sim0)
    full = problem.outputs(problem.simulate(theta, full=True), out["linear"], full=True)
    full0 = problem.outputs(problem.simulate(theta0, full=True), out0["linear"], full=True)
    index = pd.Index(problem.time_s, name="time_s")
    measured = pd.DataFrame({c.name: c.measured for c in problem.channels}, index=index)
    pred = pd.DataFrame(full["predictions"], index=index)[measured.columns]
    pred0 = pd.DataFrame(full0["predictions"], index=index)[measured.columns]
    rmse = {c: float(np.sqrt(np.mean((measured[c] - pred[c]) ** 2))) for c in measured}
    rmse0 = {c: float(np.sqrt(np.mean((measured[c] - pred0[c]) ** 2))) for c in measured}
    return CalibrationResult(
        network_initial=_with_linear(problem.network_at(theta0, problem.heat(out0["linear"])), out0["linear"],
                                     problem),
        network=_with_linear(problem.network_at(theta, problem.heat(out["linear"])), out["linear"], problem),
        estimates=estimates, linear=out["linear"], sigma={c.name: c.sigma for c in problem.channels},
        rmse_initial=rmse0, rmse=rmse, unidentifiable=unidentifiable, null_directions=null_dirs, level=level,
        cost_initial=float(r0 @ r0), cost=float(r @ r), s2=s2, evaluations=problem.evaluations,
        seconds=time.perf_counter() - start_clock, stopped=stopped, assumptions=assumptions,
        time_s=problem.time_s, measured=measured, predicted_initial=pred0, predicted=pred,
        channel_kind={c.name: c.kind for c in problem.channels},
        speed_rpm=problem.scenario.frame["speed_rpm"].to_numpy())


def _uncertainty(problem: _Problem, theta, J, s2, dof, level, lo, hi, sim: _Sim, out: dict):
    """Estimates with intervals, unidentifiable parameters and near-null directions (see module docstring).

    Projected heat amplitudes get the interval of their channel's linear regression (conditional on θ).
    """
    free = problem.free
    q = float(stats.t.ppf(0.5 + level / 2, dof))
    estimates = []
    nulls = []
    if free:
        _, sv, Vt = np.linalg.svd(J, full_matrices=False)
        smax = sv[0] if len(sv) and sv[0] > 0 else 1.0
        null = sv / smax < NULL_TOLERANCE
        for j in np.flatnonzero(null):
            v = Vt[j]
            combo = {free[i].name: round(float(v[i]), 3) for i in np.argsort(-np.abs(v)) if abs(v[i]) >= 0.2}
            nulls.append({"singular_ratio": float(sv[j] / smax), "log_combination": combo,
                          "meaning": "the data cannot tell apart changes along " + " ".join(
                              f"{c:+.2f}·log({n})" for n, c in combo.items())})
        # Covariance on the identified subspace; a parameter that loads on a null direction has no finite
        # interval (a floored inverse would leak the null direction's huge variance into every parameter).
        keep = ~null
        cov = (Vt[keep].T / sv[keep] ** 2) @ Vt[keep] * s2
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        loads = np.abs(Vt[null]).max(axis=0) >= 0.2 if null.any() else np.zeros(len(free), bool)
        se[loads] = np.inf
        for i, p in enumerate(free):
            at_bound = bool(theta[i] <= lo[i] + 1e-9 or theta[i] >= hi[i] - 1e-9)
            half = q * se[i]
            low, high = ((float(np.exp(theta[i] - half)), float(np.exp(theta[i] + half))) if half < 700
                         else (0.0, math.inf))
            estimates.append(Estimate(p.name, p.paths, float(np.exp(theta[i])), p.value, low, high, float(se[i]),
                                      at_bound, p.unit))
    idx = {n: i for i, n in enumerate(sim.net.node_names)}
    sigma = {c.name: c.sigma for c in problem.channels}
    for ch, p in problem.projected.items():
        node = idx[next(iter(next(s for s in problem.temp_sensors if s.name == ch).weights))]
        phi = sim.X[:, node] - sim.X_boundary[:, node]
        A = np.column_stack([phi, np.ones(len(phi))])
        var = np.linalg.pinv(A.T @ A)[0, 0] * s2 * sigma[ch] ** 2
        value = out["linear"][ch][p.name]
        half = q * math.sqrt(max(var, 0.0))
        low, high = max(value - half, 0.0), value + half
        estimates.append(Estimate(p.name, p.paths, value, p.value, low, high,
                                  half / q / value if value > 0 else math.inf, value <= 0.0, p.unit))
    in_null = {n for d in nulls for n in d["log_combination"]}
    unidentifiable = []
    for e in estimates:
        reasons = []
        if e.ratio > UNIDENTIFIABLE_RATIO:
            reasons.append(f"{level:.0%} interval spans a factor {e.ratio:.3g}" if math.isfinite(e.ratio)
                           else f"{level:.0%} interval reaches zero or infinity")
        if e.name in in_null:
            reasons.append("loads on a near-null singular direction of the Jacobian")
        if reasons:
            if e.at_bound:
                reasons.append("estimate at its bound")
            unidentifiable.append({"parameter": e.name, "value": e.value, "ci": [_num(e.low), _num(e.high)],
                                   "reasons": reasons,
                                   "combinations": [d["log_combination"] for d in nulls
                                                    if e.name in d["log_combination"]]})
    return estimates, unidentifiable, nulls


def _with_linear(net: Network, linear: Mapping[str, Mapping[str, float]], problem: _Problem) -> Network:
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


def predict(network: Network, scenario: Scenario, initial: np.ndarray | None = None,
            reference: np.ndarray | None = None) -> tuple[pd.DataFrame, np.ndarray]:
    """Noise-free sensor readings (°C, µm, with the network's offsets and lags) over ``scenario`` and the node
    temperatures (°C, K × N) — the calibrated model's prediction on new inputs.

    ``initial``: node temperatures at the first sample (default: rest). Displacements are relative to the node
    temperatures ``reference`` (default: the initial state), so a simulation continued from the end of the
    calibration data keeps the calibration's zero.
    """
    comp = CompiledNetwork(network)
    X = trajectory(comp, scenario, initial)
    idx = comp.index
    t = scenario.time_s
    bnd = {"ambient": scenario.frame["ambient_degC"].to_numpy(),
           "coolant": scenario.frame["coolant_inlet_degC"].to_numpy()}
    r2 = (scenario.frame["speed_rpm"].to_numpy() / network.reference_speed_rpm) ** 2
    ref = X[0] if reference is None else np.asarray(reference, dtype=float)
    Y = (X - ref) @ comp.output_matrix.T + r2[:, None] * comp.centrifugal_um[None, :]
    cols = {}
    for s in network.sensors:
        if isinstance(s, TemperatureSensor):
            v = sum(w * (X[:, idx[n]] if n in idx else bnd[n]) for n, w in s.weights.items())
            cols[s.name] = first_order_lag(v, t, s.lag_s) + s.offset_K
        else:
            cols[s.name] = Y[:, [o.name for o in network.outputs].index(s.output)] + s.offset_um
    return pd.DataFrame(cols, index=pd.Index(t, name="time_s")), X
