"""A machine's thermal network (the ``auto`` baseline or a spec) as a stochastic grey-box model: process noise on every
node, measurement noise per channel, the network's free parameters estimated by maximum likelihood through the
Kalman filter (``calibrate --stochastic``), and mechanisms tested by likelihood ratio (``diagnose --stochastic``).

States: the network's nodes (°C); time in hours; levels: the spindle-speed levels (10 rpm, as the state observer
takes them); inputs: the network's [1, ambient, coolant, signal sources…] plus (n/n_ref)² for the centrifugal
growth. Parameters of the network enter as ``free`` (FreeParameters: their own values, bounds and units, as
mechanisms declare them) or as ``factors`` (name → network paths: one multiplier ``k.<name>`` of the paths' current
values, start 1, within [0.01, 100]: how a calibrated network is refined). Outputs: the lag-free temperature sensors
reading nodes (their offset as a constant) and the displacement sensors (Σ s_i (T_i − T_i,0) + offset + centrifugal,
with T_0 the network's rest state at the first sample). Lagged temperature sensors are left out of the likelihood
(their lag is not a state here). Parameters: the free parameters plus ``sigma.<node>`` (K/√h) and ``r.<channel>`` (K
or µm)."""

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



def select_mechanisms(recording, *, seed: int = 0, alpha: float = 0.01, max_rounds: int = 3,
                      only: Sequence[str] | None = None, hidden_nodes: int = 2, registry=None,
                      progress=None) -> dict:
    """``diagnose --stochastic`` on a machine recording: the ``auto`` baseline calibrated by output error, then
    refined as a stochastic model (one multiplier per calibrated parameter, σ per node, r per channel); each round
    every registered machine mechanism at each of its places (two at most) is fitted with its own parameters
    free and the rest held at the current estimates, and the best by likelihood is accepted when its LR test
    passes at ``alpha`` / (candidates fitted) (Bonferroni). The accepted one is then refitted with every parameter
    free, and the next round starts from it. Returns the report (JSON-ready): ``baseline``, ``selection_path``,
    ``findings`` (mechanism, place, parameters, lr, df, p_value), ``rejected`` (mechanism, reason) and
    ``verdict``."""
    from scipy.stats import chi2

    from thermodrift.core.errors import InputError
    from thermodrift.core.physics import calibration as cal
    from thermodrift.core.physics.stochastic.building import BuildingMechanism
    from thermodrift.core.physics.stochastic.fit import fit

    if registry is None:
        from thermodrift.core import registry as registry_module

        registry = registry_module.default()
    say = progress or (lambda line: None)
    oe = cal.calibrate(recording, None, hidden_nodes=hidden_nodes, starts=1, seed=seed)
    factors = {e.name: tuple(e.paths) for e in oe.estimates}
    model = NetworkModel(oe.network, recording, factors=factors)
    current = fit(model, model.data, seed=seed, starts=1, information=False)
    say(f"baseline: loglik {current.loglik:.1f} ({current.n_params} parameters)")
    path = [{"name": "baseline", "loglik": current.loglik, "n_params": current.n_params}]
    findings, rejected, net, free = [], {}, oe.network, []
    ids = [m for m in registry.names("mechanism") if only is None or m in only]
    for _ in range(max_rounds):
        fitted = []
        for mid in ids:
            cls = registry.get("mechanism", mid).factory
            if issubclass(cls, BuildingMechanism) or any(f["mechanism"] == mid for f in findings):
                continue
            why = cls.missing_drivers(recording)
            places = [] if why else cls.places(net)
            if why or not places:
                rejected[mid] = f"skipped: {why}" if why else (cls.unplaced(net) or "skipped: no place in the network")
                continue
            for options in places[:2]:
                try:
                    net2, new = cls(**options).declare(net)
                except InputError as err:
                    rejected[mid] = f"skipped: {err}"
                    continue
                m2 = NetworkModel(net2, recording, free=[*free, *new], factors=factors, start=current.values)
                e2 = fit(Frozen(m2, current.values), m2.data, seed=seed, starts=1, information=False)
                fitted.append((mid, options, new, m2, e2))
                say(f"  {mid} {options or ''}: loglik {e2.loglik:.1f}")
        if not fitted:
            break
        mid, options, new, m2, e2 = max(fitted, key=lambda c: c[4].loglik)
        df = len(new)
        lr = max(2.0 * (e2.loglik - current.loglik), 0.0)
        p = float(chi2.sf(lr, df))
        level = alpha / len(fitted)
        step = {"name": mid, "place": options, "loglik": e2.loglik, "n_params": current.n_params + df, "lr": lr,
                "df": df, "p_value": p, "level": level, "accepted": p < level}
        path.append(step)
        for other, *_ in fitted:
            if other != mid:
                rejected.setdefault(other, f"explains less than {mid} (likelihood)")
        if p >= level:
            rejected[mid] = f"not significant: LR {lr:.1f} on {df} parameter(s), p = {p:.3g} ≥ {level:.3g}"
            break
        rejected.pop(mid, None)
        m2 = NetworkModel(m2.network, recording, free=[*free, *new], factors=factors,
                          start={**current.values, **e2.values})
        current = fit(m2, m2.data, seed=seed, starts=1, information=False)
        net, free = m2.network, [*free, *new]
        findings.append({"mechanism": mid, "place": options, "lr": lr, "df": df, "p_value": p,
                         "parameters": {f.name: current.values[f.name] for f in new}})
    verdict = ("missing: " + ", ".join(f["mechanism"] for f in findings)) if findings else "none: no mechanism " \
        "raises the innovations likelihood significantly"
    return {"kind": "stochastic_mechanisms", "baseline": {"network": oe.network.name, "loglik": path[0]["loglik"],
                                                         "n_params": path[0]["n_params"], "channels": model.channels},
            "selection_path": path, "findings": findings,
            "rejected": [{"mechanism": k, "reason": v} for k, v in rejected.items()], "verdict": verdict,
            "alpha": alpha}


class Frozen:
    """``model`` with the parameters named in ``fixed`` held at those values (the others searched)."""

    def __init__(self, model, fixed: Mapping[str, float]):
        self.name, self.model = model.name, model
        self.fixed = {p.name: fixed[p.name] for p in model.parameters if p.name in fixed}
        self.parameters = tuple(p for p in model.parameters if p.name not in self.fixed)

    def system(self, values: Mapping[str, float]) -> System:
        return self.model.system({**self.fixed, **values})
