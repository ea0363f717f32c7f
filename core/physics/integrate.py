"""Integrate a :class:`Network` over a :class:`Scenario`, exactly for piecewise-constant inputs.

Inputs are held over each step (zero-order hold). At an operating level — spindle speed, coolant flow and step
size — the network is linear and time-invariant::

    dT/dt = A T + B u,   u = [1, T_ambient, T_coolant_inlet, P_1 … P_m]   (P_j: signal-driven sources, W)
    T_{k+1} = Φ T_k + Γ u_k

``method="exact"`` takes Φ = e^{A·dt} and Γ = ∫ e^{A s} ds · B from one matrix exponential of the augmented
matrix [[A, B], [0, 0]]·dt (Van Loan), so the result is exact at any step size; ``"backward_euler"`` takes
Φ = (I − dt·A)⁻¹, Γ = dt·Φ·B (L-stable, first order in dt). Either way Φ and Γ are computed once per distinct
level and reused for every step at that level.

Long segments at one level are propagated in the Schur basis of Φ = Q R Qᴴ (orthogonal, so well conditioned
even where Φ is nearly defective, as along a coolant chain): R is triangular, so the modes are solved from
the last to the first, each a first-order recursion run by ``scipy.signal.lfilter`` in C, with the modes
already solved as its input. A 46 h programme at 15 s on 15 nodes then costs a few matrix exponentials and
Schur decompositions plus O(steps · nodes²) array work.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd
from scipy.linalg import expm, lu_factor, lu_solve, schur
from threadpoolctl import ThreadpoolController

from thermodrift.core.errors import InputError
from thermodrift.core.physics.network import BOUNDARIES, Network
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.physics.sensors import measure

METHODS = ("exact", "backward_euler")
_SCHUR_MIN_STEPS = 64  # shorter segments are stepped directly: lfilter's per-call overhead would dominate
# Multithreaded BLAS only adds hand-offs on 5–20-node matrices; on a busy machine it made a simulation 3–6×
# slower, so simulations run single-threaded (threadpoolctl comes with scikit-learn).
_THREADS = ThreadpoolController()


class CompiledNetwork:
    """A validated network ready to simulate: index maps, output matrix and per-level step matrices.

    Build one per parameter set and reuse it: (Φ, Γ) of every operating level met so far are cached, so
    re-simulating the same programme (different initial state, a sub-range) skips the matrix exponentials.
    ``trajectory`` gives node temperatures as an array, ``displacements`` the outputs in µm — no pandas, for fitting.
    """

    def __init__(self, network: Network):
        self.network = network.validate()
        self.names = network.node_names
        self.index = {n: i for i, n in enumerate(self.names)}
        self.capacity = np.array([n.capacity_J_K for n in network.nodes])
        self.signal_sources = [s for s in network.sources if hasattr(s, "signal_power")]
        self.n_inputs = 1 + len(BOUNDARIES) + len(self.signal_sources)
        self._levels: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self._schur: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        S = np.zeros((len(network.outputs), len(self.names)))
        for r, o in enumerate(network.outputs):
            for node, s in o.sensitivity_um_K.items():
                S[r, self.index[node]] += s
            for hot, cold, k in o.tilt_pairs():
                S[r, self.index[hot]] += k
                S[r, self.index[cold]] -= k
        self.output_matrix = S
        self.centrifugal_um = np.array([o.centrifugal_um for o in network.outputs])

    def matrices(self, speed_rpm: float, coolant_flow: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """A (1/s) and B at one operating level: dT/dt = A T + B u with u = [1, T_amb, T_cool, P_1 … P_m].

        Column 0 of B holds the speed-driven heat (K/s), columns 1–2 the boundary conductances over C (1/s), the
        rest the split fractions over C (K/J) of the signal-driven sources (:attr:`signal_sources`, in order).
        """
        net, idx = self.network, self.index
        r = speed_rpm / net.reference_speed_rpm
        N = len(self.names)
        L = np.zeros((N, N))  # heat-flow matrix: C dT/dt = −L T + Bq u
        Bq = np.zeros((N, self.n_inputs))
        col = {b: 1 + i for i, b in enumerate(BOUNDARIES)}
        for e in net.edges:
            G, i = e.conductance(r), idx[e.a]
            L[i, i] += G
            if e.b in col:
                Bq[i, col[e.b]] += G
            else:
                j = idx[e.b]
                L[j, j] += G
                L[i, j] -= G
                L[j, i] -= G
        for a in net.advections:
            G, i = a.mdot_cp_W_K * coolant_flow, idx[a.downstream]
            L[i, i] += G
            if a.upstream in col:
                Bq[i, col[a.upstream]] += G
            else:
                L[i, idx[a.upstream]] -= G
        for s in net.sources:
            if hasattr(s, "speed_terms"):
                heat, linear = s.speed_terms(r)
                for node, q in heat.items():
                    Bq[idx[node], 0] += q
                for row, c, g in linear:
                    L[idx[row], idx[c]] -= g
        for j, s in enumerate(self.signal_sources):
            for node, f in s.split.items():
                Bq[idx[node], 1 + len(BOUNDARIES) + j] += f
        return -L / self.capacity[:, None], Bq / self.capacity[:, None]

    def inputs(self, scenario: Scenario) -> np.ndarray:
        """u_k for every sample: (K, n_inputs)."""
        f = scenario.frame
        cols = [np.ones(len(f)), f["ambient_degC"].to_numpy(), f["coolant_inlet_degC"].to_numpy()]
        return np.column_stack([*cols, *self.signal_inputs(scenario).T])

    def signal_inputs(self, scenario: Scenario) -> np.ndarray:
        """The signal-driven sources' power (W) for every sample: (K, len(signal_sources)), the inputs' last
        columns."""
        f = scenario.frame
        signals = {c: f[c].to_numpy() for c in ("cutting_power_W", "axis_velocity_mm_min")}
        return np.column_stack([np.asarray(s.signal_power(signals), dtype=float) for s in self.signal_sources]
                               or [np.zeros((len(f), 0))])

    def step(self, speed_rpm: float, coolant_flow: float, dt_s: float, method: str) -> tuple[np.ndarray, np.ndarray]:
        """Cached (Φ, Γ) for one level and step size."""
        key = (speed_rpm, coolant_flow, dt_s, method)
        if key not in self._levels:
            A, B = self.matrices(speed_rpm, coolant_flow)
            N, M = B.shape
            if method == "exact":
                aug = np.zeros((N + M, N + M))
                aug[:N, :N], aug[:N, N:] = A * dt_s, B * dt_s
                E = expm(aug)
                self._levels[key] = (E[:N, :N], E[:N, N:])
            else:
                lu = lu_factor(np.eye(N) - dt_s * A)
                self._levels[key] = (lu_solve(lu, np.eye(N)), lu_solve(lu, dt_s * B))
        return self._levels[key]

    def _propagate(self, key: tuple, x0: np.ndarray, W: np.ndarray) -> np.ndarray:
        """States after each step of x_{k+1} = Φ x_k + W[k] at level ``key`` (see :meth:`step`): (len(W), N)."""
        Phi = self._levels[key][0]
        if len(W) >= _SCHUR_MIN_STEPS and key not in self._schur:
            self._schur[key] = schur(Phi, output="complex", check_finite=False)
        return propagate(Phi, x0, W, self._schur.get(key))

    def trajectory(self, scenario: Scenario, *, initial: str | float | Mapping[str, float] | np.ndarray = "steady",
                   method: str = "exact") -> np.ndarray:
        """Node temperatures (°C) at every sample of ``scenario``: an array (samples, nodes) in node order.

        ``initial`` as in :func:`simulate`. Runs single-threaded BLAS (faster for these small matrices).
        """
        if method not in METHODS:
            raise InputError(f"unknown integration method {method!r}", hint=f"use one of {', '.join(METHODS)}")
        with _THREADS.limit(limits=1, user_api="blas"):
            f = scenario.frame
            t, speed, flow = scenario.time_s, f["speed_rpm"].to_numpy(), f["coolant_flow"].to_numpy()
            U = self.inputs(scenario)
            X = np.empty((len(t), len(self.names)))
            rest = U[0].copy()
            rest[1 + len(BOUNDARIES):] = 0.0
            X[0] = _initial_state(self, initial, 0.0, flow[0], rest)
            dt = np.round(np.diff(t), 9)
            keys = np.column_stack([speed[:-1], flow[:-1], dt])
            change = np.flatnonzero(np.any(keys[1:] != keys[:-1], axis=1)) + 1
            for a, b in zip(np.r_[0, change], np.r_[change, len(t) - 1]):
                key = (float(speed[a]), float(flow[a]), float(dt[a]), method)
                _, Gam = self.step(*key)
                X[a + 1:b + 1] = self._propagate(key, X[a], U[a:b] @ Gam.T)
        return X

    def displacements(self, X: np.ndarray, speed_rpm: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
        """Output displacements (µm, samples × outputs) of node temperatures ``X`` (°C, samples × nodes, or one
        row) at ``speed_rpm``: thermal growth relative to the node temperatures ``reference`` (default: the first
        row of ``X``) plus the centrifugal term."""
        X = np.atleast_2d(X)
        r2 = np.atleast_1d(np.asarray(speed_rpm, dtype=float) / self.network.reference_speed_rpm) ** 2
        ref = X[0] if reference is None else reference
        return (X - ref) @ self.output_matrix.T + r2[:, None] * self.centrifugal_um[None, :]

    def steady_state(self, speed_rpm: float, coolant_flow: float, u: np.ndarray) -> np.ndarray:
        """Temperatures (°C) at which the network is in equilibrium under constant inputs ``u``."""
        A, B = self.matrices(speed_rpm, coolant_flow)
        try:
            return np.linalg.solve(A, -B @ u)
        except np.linalg.LinAlgError:
            raise InputError(f"network {self.network.name!r} has no steady state at {speed_rpm:g} rpm") from None

    def time_constants_s(self, speed_rpm: float = 0.0, coolant_flow: float = 1.0) -> np.ndarray:
        """Time constants −1/Re(λ) of the network at a level (s), longest first."""
        lam = np.linalg.eigvals(self.matrices(speed_rpm, coolant_flow)[0])
        return np.sort(-1.0 / lam.real)[::-1]


@dataclass
class SimulationResult:
    """Node temperatures (°C) and output displacements (µm), both indexed by ``time_s`` like the scenario."""

    network: Network
    scenario: Scenario
    temperatures: pd.DataFrame
    displacements: pd.DataFrame

    @property
    def boundaries(self) -> pd.DataFrame:
        """Boundary temperatures (°C): ``ambient`` and ``coolant`` (the coolant inlet)."""
        f = self.scenario.frame
        return pd.DataFrame({"ambient": f["ambient_degC"], "coolant": f["coolant_inlet_degC"]})

    def measure(self, seed: int | None = None) -> pd.DataFrame:
        """What the network's sensors read (°C, µm), with noise drawn from ``seed`` (None: no noise)."""
        return measure(self.network.sensors, pd.concat([self.temperatures, self.boundaries], axis=1),
                       self.displacements, seed)

    def to_recording(self, seed: int | None = None, source: str | None = None):
        """A :class:`thermodrift.core.recording.Recording` of the sensors plus speed, inputs and conditions."""
        from thermodrift.core.recording import Channel, Recording

        f = self.scenario.frame
        columns = {"spindle_rpm": f["speed_rpm"].to_numpy()}
        channels = {"spindle_rpm": Channel("spindle_rpm", "speed", "rpm", {})}
        for col, role, unit in (("cutting_power_W", "cutting_power", "W"),
                                ("axis_velocity_mm_min", "axis_velocity", "mm_min")):
            values = f[col].to_numpy()
            if values.any():
                columns[col] = values
                channels[col] = Channel(col, role, unit, {})
        readings = self.measure(seed)
        for s in self.network.sensors:
            columns[s.name] = readings[s.name].to_numpy()
            if hasattr(s, "output"):
                channels[s.name] = Channel(s.name, "displacement", "um", {"axis": self.network.output(s.output).axis})
            else:
                meta = {"location": s.location} if s.location else {}
                channels[s.name] = Channel(s.name, s.role, "degC", meta)
        labels = f["condition"].astype(str).to_numpy()
        if (labels != "").any():
            columns["condition"] = labels
            channels["condition"] = Channel("condition", "condition", None, {})
        data = pd.DataFrame(columns, index=pd.Index(f.index.to_numpy(), name="time_s"))
        return Recording(data, channels, source=source or f"simulated:{self.network.name}")


def propagate(Phi: np.ndarray, x0: np.ndarray, W: np.ndarray,
              schur_form: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """States after each step of x_{k+1} = Φ x_k + W[k]: (len(W), N). The project's one linear propagator
    (simulation, calibration and the state observer of the physics models use it).

    Short runs are stepped directly; long ones in the Schur basis Φ = Q R Qᴴ (``schur_form`` = (R, Q), computed
    if not given): the modes are solved from the last to the first, each a first-order recursion run by
    ``scipy.signal.lfilter`` in C with the modes already solved as its input.
    """
    K, N = W.shape
    if K < _SCHUR_MIN_STEPS:
        out, x = np.empty((K, N)), x0
        for k in range(K):
            x = Phi @ x + W[k]
            out[k] = x
        return out
    from scipy.signal import lfilter  # imported here: ~1 s, not to be paid when plugins load

    R, Q = schur_form if schur_form is not None else schur(Phi, output="complex", check_finite=False)
    z0 = Q.conj().T @ x0
    V = W @ Q.conj()                      # inputs in the Schur basis, one row per step
    Z = np.empty((K + 1, N), dtype=complex)  # Z[k] = state before step k; Z[K] = final
    Z[0] = z0
    for i in range(N - 1, -1, -1):
        v = V[:, i] + Z[:-1, i + 1:] @ R[i, i + 1:] if i < N - 1 else V[:, i]
        lam = R[i, i]
        Z[1:, i], _ = lfilter([1.0], [1.0, -lam], v, zi=np.array([lam * z0[i]]))
    return (Z[1:] @ Q.T).real


def simulate(network: Network | CompiledNetwork, scenario: Scenario, dt_s: float | None = None, *,
             method: str = "exact", initial: str | float | Mapping[str, float] | np.ndarray = "steady",
             ) -> SimulationResult:
    """Simulate ``network`` over ``scenario`` (resampled to ``dt_s`` if given).

    ``initial``: "steady" (at rest in equilibrium with the first sample's ambient and coolant: spindle stopped,
    no cutting or axis motion), one temperature for all nodes (°C), or temperatures by node name / in node
    order. Displacements are zero at the initial state. For repeated simulations without pandas (calibration),
    use :meth:`CompiledNetwork.trajectory` and :meth:`CompiledNetwork.outputs` directly.
    """
    comp = network if isinstance(network, CompiledNetwork) else CompiledNetwork(network)
    if dt_s is not None:
        scenario = scenario.resample(dt_s)
    X = comp.trajectory(scenario, initial=initial, method=method)
    index = scenario.frame.index
    temps = pd.DataFrame(X, index=index, columns=comp.names)
    Y = comp.displacements(X, scenario.frame["speed_rpm"].to_numpy())
    disp = pd.DataFrame(Y, index=index, columns=[o.name for o in comp.network.outputs])
    return SimulationResult(comp.network, scenario, temps, disp)


def _initial_state(comp: CompiledNetwork, initial, speed: float, flow: float, u0: np.ndarray) -> np.ndarray:
    if isinstance(initial, str):
        if initial != "steady":
            raise InputError(f"unknown initial state {initial!r}", hint="use 'steady', a temperature or a mapping")
        return comp.steady_state(speed, flow, u0)
    if isinstance(initial, Mapping):
        missing = set(comp.names) - set(initial)
        if missing:
            raise InputError(f"initial temperatures missing for nodes {sorted(missing)}")
        return np.array([float(initial[n]) for n in comp.names])
    x = np.broadcast_to(np.asarray(initial, dtype=float), (len(comp.names),)).copy()
    return x
