"""A machine's thermal network (the ``auto`` baseline or a spec) as a stochastic grey-box model: process noise on
every node, measurement noise per channel, the network's free parameters estimated by maximum likelihood through
the Kalman filter (``calibrate --stochastic``), and mechanisms tested by likelihood ratio (``diagnose
--stochastic``).

States: the network's nodes (°C); time in hours; levels: the spindle-speed levels (10 rpm, as the state observer
takes them); inputs: the network's [1, ambient, coolant, signal sources…] plus (n/n_ref)² for the centrifugal
growth. Parameters of the network enter as ``free`` (FreeParameters: their own values, bounds and units, as
mechanisms declare them) or as ``factors`` (name → network paths: one multiplier ``k.<name>`` of the paths' current
values, start 1, within [0.01, 100]: how a calibrated network is refined). Outputs: the lag-free temperature sensors reading nodes (their offset as a constant) and the displacement
sensors (Σ s_i (T_i − T_i,0) + offset + centrifugal, with T_0 the network's rest state at the first sample).
Lagged temperature sensors are left out of the likelihood (their lag is not a state here). Parameters: the free
parameters plus ``sigma.<node>`` (K/√h) and ``r.<channel>`` (K or µm).
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from thermodrift.core.physics.calibration.free import FreeParameter
from thermodrift.core.physics.integrate import CompiledNetwork
from thermodrift.core.physics.network import Network
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.physics.stochastic.fit import Param
from thermodrift.core.physics.stochastic.sde import Series, System

HOUR_S = 3600.0
SPEED_STEP_RPM = 10.0


class NetworkModel:
    """See the module docstring. ``free``: FreeParameters to estimate (``projected`` ones too: they are searched
    like the others here); ``factors``: name → paths; ``sigma`` and ``r``: start values of the noise (K/√h; K or µm
    by channel); ``start``: start values by parameter name."""

    def __init__(self, network: Network, recording, *, free: Sequence[FreeParameter] = (),
                 factors: Mapping[str, Sequence[str]] | None = None, sigma: float = 0.05,
                 r: Mapping[str, float] | None = None, start: Mapping[str, float] | None = None):
        self.name = network.name
        self.network = network
        self.free = list(free)
        known = network.parameters()
        self.factors = {k: {p: known[p] for p in paths} for k, paths in (factors or {}).items()}
        scen = Scenario.from_recording(recording, speed_step_rpm=SPEED_STEP_RPM)
        comp = CompiledNetwork(network)
        speed = scen.frame["speed_rpm"].to_numpy() if "speed_rpm" in scen.frame else np.zeros(len(scen.frame))
        self.levels = np.unique(speed)
        level = np.searchsorted(self.levels, speed)
        cols = set(recording.data.columns)
        self.temp_sensors = [s for s in network.temperature_sensors
                             if s.name in cols and s.lag_s == 0 and all(n in comp.index for n in s.weights)]
        self.disp_sensors = [s for s in network.displacement_sensors if s.name in cols]
        self.channels = [s.name for s in self.temp_sensors] + [s.name for s in self.disp_sensors]
        if not self.channels:
            raise ValueError("no lag-free temperature sensor or displacement sensor of the network is in the recording")
        u = np.column_stack([comp.inputs(scen), (speed / network.reference_speed_rpm) ** 2])
        y = recording.data[self.channels].to_numpy(dtype=float)
        self.data = Series.of(scen.time_s / HOUR_S, u, y, level)
        start = dict(start or {})
        params = [Param(f.name, float(start.get(f.name, f.value)), f.low, f.high, f.unit) for f in self.free]
        params += [Param(f"k.{k}", float(start.get(f"k.{k}", 1.0)), 1e-2, 1e2, "× start") for k in self.factors]
        params += [Param(f"sigma.{n}", float(start.get(f"sigma.{n}", sigma)), 1e-6, 1e3, "K/√h")
                   for n in comp.names]
        resid = np.nanstd(np.diff(y, axis=0), axis=0) / math.sqrt(2)
        for k, c in enumerate(self.channels):
            unit = "K" if k < len(self.temp_sensors) else "µm"
            r0 = (r or {}).get(c, max(float(resid[k]), 1e-3))
            params.append(Param(f"r.{c}", float(start.get(f"r.{c}", r0)), 1e-5, 1e3, unit))
        self.parameters = tuple(params)

    def network_at(self, values: Mapping[str, float]) -> Network:
        """The network with the free parameters at ``values``."""
        new = {p: f.network_value(values[f.name]) for f in self.free for p in f.paths}
        for k, base in self.factors.items():
            new.update({p: v * values[f"k.{k}"] for p, v in base.items()})
        return self.network.with_values(new)

    def system(self, values: Mapping[str, float]) -> System:
        net = self.network_at(values)
        comp = CompiledNetwork(net)
        mats = [comp.matrices(float(s)) for s in self.levels]
        A = np.stack([a for a, _ in mats]) * HOUR_S
        B = np.stack([np.column_stack([b, np.zeros(len(b))]) for _, b in mats]) * HOUR_S
        n, m = A.shape[1], B.shape[2]
        rows, D = [], np.zeros((len(self.channels), m))
        for k, s in enumerate(self.temp_sensors):
            row = np.zeros(n)
            for node, w in s.weights.items():
                row[comp.index[node]] += w
            rows.append(row)
            D[k, 0] = s.offset_K
        if self.disp_sensors:
            u0 = self.data.u[0]
            x0 = np.linalg.lstsq(A[self.data.level[0]], -B[self.data.level[0]] @ u0, rcond=None)[0]
            outputs = [o.name for o in net.outputs]
            for k, s in enumerate(self.disp_sensors, start=len(self.temp_sensors)):
                i = outputs.index(s.output)
                rows.append(comp.output_matrix[i])
                D[k, 0] = s.offset_um - comp.output_matrix[i] @ x0
                D[k, -1] = comp.centrifugal_um[i]
        sigma = np.array([values[f"sigma.{name}"] for name in comp.names])
        r = np.array([values[f"r.{c}"] for c in self.channels])
        return System(A, B, np.array(rows), D, sigma, r)

