"""The ``auto`` baseline network of a recording, built from its manifest alone.

It assumes
exactly the following and nothing else (:data:`AUTO_ASSUMPTIONS`, also written into ``calibration.json`` —
the missing-physics finder starts from here):

1. One node per temperature channel (the sensor reads its node directly: no lag, a constant offset), plus
   ``hidden_nodes`` unobserved nodes (default 2) that act only on the displacements (none without a
   displacement channel: they would be unobservable).
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

Free parameters: G_i of every node and p (searched in log space), and Q_i ≥ 0 of every temperature node — its
node is read by one sensor and touches only the ambient, so the reading is linear in Q_i and Q_i is projected
out with the offset. Start values come from each channel's first warm-up (:func:`step_response_start`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from thermodrift.core.errors import InputError
from thermodrift.core.physics.calibration.free import FreeParameter
from thermodrift.core.physics.network import (BOUNDARIES, BearingSource, DisplacementSensor, Edge, Network, Node,
                                              Output, TemperatureSensor)
from thermodrift.core.recording import speed_segments

AUTO_CAPACITY_J_K = 1.0e4
AUTO_AMBIENT_DEGC = 20.0

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


@dataclass
class AutoBaseline:
    """The ``auto`` network of a recording, its free parameters and what it assumes."""

    network: Network
    free: list[FreeParameter]
    assumptions: tuple[str, ...] = AUTO_ASSUMPTIONS
    channel_nodes: dict[str, str] = field(default_factory=dict)  # temperature column -> node
    time_constants_s: dict[str, float] = field(default_factory=dict)  # channel -> first warm-up τ (s)


def _safe(name: str) -> str:
    return re.sub(r"[^0-9A-Za-z_]+", "_", str(name)).strip("_") or "ch"


def _unique(names: list[str], base: str) -> str:
    name, i = base, 2
    while name in names or name in BOUNDARIES:
        name, i = f"{base}_{i}", i + 1
    names.append(name)
    return name


def step_response_start(time_s: np.ndarray, temperature: np.ndarray, speed_rpm: np.ndarray,
                        n_ref: float, exponent: float) -> tuple[float, float]:
    """Start values (time constant s, heat per capacity at n_ref K/s) read off the first warm-up of a channel.

    The rise over the first run is T(t) − T(start); its end value K is the steady rise (the run is taken as
    long enough), τ the time to 63 % of K. Heat at n_ref: K/τ·(n_ref/n)^p per unit capacity.
    """
    runs = [s for s in speed_segments(time_s, speed_rpm) if s[2] > 0]
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


def _grouped(free: list[FreeParameter], group_of: dict[str, str],
             g_bounds: tuple[float, float]) -> list[FreeParameter]:
    """``free`` with the conductances G[node] replaced by one factor per node group (bounds keep every G within
    ``g_bounds``)."""
    conductances = [p for p in free if p.name.startswith("G[")]
    out = [p for p in free if not p.name.startswith("G[")]
    by_group: dict[str, list[FreeParameter]] = {}
    for p in conductances:
        by_group.setdefault(group_of[p.name[2:-1]], []).append(p)
    for group, members in by_group.items():
        starts = tuple(p.value for p in members)
        low, high = max(g_bounds[0] / g for g in starts), min(g_bounds[1] / g for g in starts)
        out.append(FreeParameter(f"G[{group}]×", tuple(p.paths[0] for p in members), 1.0, min(low, 1.0),
                                 max(high, 1.0), "1", scales=starts))
    return out


def auto_network(recording, hidden_nodes: int | tuple[float, ...] = 2, capacity_J_K: float = AUTO_CAPACITY_J_K,
                 heat_exponent: float = 1.5, grouped: bool = False) -> AutoBaseline:
    """The baseline network of ``recording`` from its manifest alone (see the module docstring).

    Start values come from each temperature channel's first warm-up (:func:`step_response_start`); hidden
    nodes start with time constants log-spaced over 0.5–4 h. Node groups are guesses for the mechanism library:
    temperature nodes rising ≥ 50 % of the largest rise are ``bearing``, ≥ 10 % ``housing``, else ``structure``;
    hidden nodes are ``shaft``. ``hidden_nodes`` may instead give the hidden nodes' start time constants (h), one
    per node (the missing-physics finder chooses them on held-out data). ``grouped``: the conductances of the
    temperature nodes of one group share one free factor on their step-response starts (``G[bearing]×`` …; a parameterisation the data can identify
    where one conductance per node is not), hidden nodes keep one conductance each.
    """
    speed = recording.speed
    if speed is None or not (speed.to_numpy() > 0).any():
        raise InputError(f"{recording.source}: the auto network needs a speed channel with the spindle running",
                         hint="give the speed column role 'speed' in the manifest, or pass --network spec.yaml")
    temps = recording.temperatures
    disps = recording.displacements
    hidden_tau_h = None
    if isinstance(hidden_nodes, (tuple, list)):
        hidden_tau_h, hidden_nodes = tuple(float(x) for x in hidden_nodes), len(hidden_nodes)
    if temps.shape[1] == 0 and hidden_nodes == 0:
        raise InputError(f"{recording.source}: no temperature channel and no hidden node to build a network from")
    if disps.shape[1] == 0:
        hidden_nodes = 0  # a hidden node acts only on displacements: without one it is unobservable
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
    if grouped:
        free = _grouped(free, {n.name: n.group for n in nodes}, g_bounds)
    taus = (np.array(hidden_tau_h) if hidden_tau_h is not None else np.geomspace(0.5, 4.0, hidden_nodes)
            if hidden_nodes > 1 else np.full(hidden_nodes, 1.5))
    for k, tau in enumerate(taus[:hidden_nodes] * 3600.0):
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
    return AutoBaseline(net, free, AUTO_ASSUMPTIONS, channel_nodes, {c: tau for c, (tau, _) in starts.items()})
