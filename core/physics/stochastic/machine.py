"""A machine's thermal network (the ``auto`` baseline or a spec) as a stochastic grey-box model: process noise on every
node, measurement noise per channel, the network's free parameters estimated by maximum likelihood through the
Kalman filter (``calibrate --stochastic``), and mechanisms tested by likelihood ratio (``diagnose --stochastic``).

States: the network's nodes (°C); time in hours; levels: the spindle-speed levels (10 rpm, as the state observer
takes them); inputs: the network's [1, ambient, coolant, signal sources…] plus (n/n_ref)² for the centrifugal
growth. Parameters of the network enter as ``free`` (FreeParameters: their own values, bounds and units, as
mechanisms declare them) or as ``factors`` (name → network paths: one multiplier ``k.<name>`` of the paths' current
values, start 1, within [0.01, 100]: how a calibrated network is refined). Outputs: the lag-free temperature sensors
reading nodes (their offset as a constant) and the displacement sensors (Σ s_i (T_i − T_i,0) + offset + centrifugal,
with T_0 the network's rest state at the first sample). A lagged temperature sensor reads one more state, the
lag error of its first-order lag (dT_s/dt = (Σ w_i T_i − T_s)/τ_s): z = (T_s − Σ w_i T_i)/``LAG_SCALE``, read as
Σ w_i T_i + ``LAG_SCALE``·z, no process noise of its own. So a sensor lag nests: as τ_s → 0, z → 0 and the model
reads the nodes themselves; the small scale makes the filter's initial state (shifted to the first reading along
the readings' pseudo-inverse) move the nodes, not z, as it does without the lag. Parameters: the free parameters plus ``sigma.<node>``
(K/√h) and ``r.<channel>`` (K or µm)."""

from __future__ import annotations

import dataclasses
import math
from typing import Mapping, Sequence

import numpy as np

from thermodrift.core.physics.calibration.free import FreeParameter
from thermodrift.core.physics.integrate import CompiledNetwork
from thermodrift.core.physics.network import BOUNDARIES, Network
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.physics.stochastic.fit import Param
from thermodrift.core.physics.stochastic.sde import Series, System

HOUR_S = 3600.0
LAG_SCALE = 0.01  # K per unit of a lag state (see the module docstring)
SPEED_STEP_RPM = 10.0
SIGNALS_FROM = 1 + len(BOUNDARIES)  # the inputs' first signal-source column (after 1, ambient, coolant)


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
                             if s.name in cols and all(n in comp.index for n in s.weights)]
        self.disp_sensors = [s for s in network.displacement_sensors if s.name in cols]
        self.channels = [s.name for s in self.temp_sensors] + [s.name for s in self.disp_sensors]
        if not self.channels:
            raise ValueError("no temperature sensor or displacement sensor of the network is in the recording")
        u = np.column_stack([comp.inputs(scen), (speed / network.reference_speed_rpm) ** 2])
        self._scenario = scen
        self._signal_at = u[:, SIGNALS_FROM:comp.n_inputs]  # the signal sources' power (W) at the network's own values
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
        """The network with the free parameters at ``values``, then the multipliers ``k.<name>`` on their paths
        (on the free value where a mechanism's parameter sets a multiplied path: its offset from the parent's
        value then nests, e.g. an exponent shift of 0 gives the parent's calibrated exponent)."""
        new = {p: v for f in self.free for p, v in f.path_values(values[f.name]).items()}
        for k, base in self.factors.items():  # a multiplier acts on a free parameter's value too (same path)
            new.update({p: new.get(p, v) * values[f"k.{k}"] for p, v in base.items()})
        return self.network.with_values(new)

    def system(self, values: Mapping[str, float]) -> System:
        net = self.network_at(values)
        comp = CompiledNetwork(net)
        mats = [comp.matrices(float(s)) for s in self.levels]
        A = np.stack([a for a, _ in mats]) * HOUR_S
        B = np.stack([np.column_stack([b, np.zeros(len(b))]) for _, b in mats]) * HOUR_S
        B[:, :, SIGNALS_FROM:comp.n_inputs] *= self._signal_scales(comp)
        n, m = A.shape[1], B.shape[2]
        lags = [s for s in net.temperature_sensors if s.name in self.channels and s.lag_s > 0]
        if lags:  # one lag state per lagged sensor (see the module docstring)
            A = np.pad(A, ((0, 0), (0, len(lags)), (0, len(lags))))
            B = np.pad(B, ((0, 0), (0, len(lags)), (0, 0)))
        sensors = {s.name: s for s in net.temperature_sensors}  # with the lags at ``values``
        rows, D, j = [], np.zeros((len(self.channels), m)), n
        for k, s in enumerate(sensors[t.name] for t in self.temp_sensors):
            row = np.zeros(n + len(lags))
            for node, w in s.weights.items():
                row[comp.index[node]] += w
            if s.lag_s > 0:  # z = (T_s − Σ w T)/LAG_SCALE: dz/dt = −z/τ − Σ w dT/dt / LAG_SCALE
                A[:, j, :n] = -np.einsum("i,lik->lk", row[:n], A[:, :n, :n]) / LAG_SCALE
                B[:, j] = -np.einsum("i,lik->lk", row[:n], B[:, :n]) / LAG_SCALE
                A[:, j, j] = -HOUR_S / s.lag_s
                row[j] = LAG_SCALE
                j += 1
            rows.append(row)
            D[k, 0] = s.offset_K
        if self.disp_sensors:
            u0 = self.data.u[0]
            x0 = np.linalg.lstsq(A[self.data.level[0]][:n, :n], -B[self.data.level[0]][:n] @ u0, rcond=None)[0]
            outputs = [o.name for o in net.outputs]
            for k, s in enumerate(self.disp_sensors, start=len(self.temp_sensors)):
                i = outputs.index(s.output)
                rows.append(np.pad(comp.output_matrix[i], (0, len(lags))))
                D[k, 0] = s.offset_um - comp.output_matrix[i] @ x0
                D[k, -1] = comp.centrifugal_um[i]
        sigma = np.array([values[f"sigma.{name}"] for name in comp.names] + [0.0] * len(lags))
        r = np.array([values[f"r.{c}"] for c in self.channels])
        return System(A, B, np.array(rows), D, sigma, r)

    def _signal_scales(self, comp: CompiledNetwork) -> np.ndarray:
        """Each signal source's power at these values over its input column (computed once, at the network's own
        values): a source's parameter (a cutting fraction, a drive's power) scales its input, and the inputs of
        the series stay fixed. The least-squares scale, exact for the built-in sources (linear in their
        parameters)."""
        now, ref = comp.signal_inputs(self._scenario), self._signal_at
        energy = (ref * ref).sum(axis=0)
        return np.where(energy > 0, (now * ref).sum(axis=0) / np.where(energy > 0, energy, 1.0), 1.0)


OFF_REACH = 1e-3   # how much lower a positive parameter's low bound goes in a candidate fit (:func:`reaching_off`)
NESTED_GAIN = 0.5  # log-likelihood units: a candidate gaining less than this over its parent is nested (LR < 1)
FAST_HEATING_S = 60.0  # the spindle nose heats over minutes: a mechanism acting at once (``at_once``) is told from
                       # that heating only when samples come at least this often (s)


def nested_start(mechanism, before: Network, new: Sequence[FreeParameter]) -> dict[str, float]:
    """Where each of a mechanism's new parameters switches it off, so that its extension starts at its parent's
    likelihood (as :func:`.selection.extension_starts` does for the buildings): a parameter whose paths the parent
    already has takes the parent's value back (an offset from the old value: an exponent shift, an added lag or
    sensitivity, 0; an existing conductance: itself), a new one the mechanism's declared neutral value (a new
    conductance, gain, power or fraction: 0); both clipped into the parameter's bounds (a positive amplitude's
    low bound, 1e-3 of its start; a lag's, 1 s). Some mechanisms cannot be switched off by their free parameters:
    the slow structural mode's conductance into its new node is held fixed (its τ and gain are free), so its
    extension never reduces to the parent exactly; :func:`select_mechanisms` names such candidates."""
    known = before.parameters()
    neutral = _neutral(mechanism)
    out = {}
    for f in new:
        old = [known[p] / (f.scales[k] if f.scales else 1.0) for k, p in enumerate(f.paths) if p in known]
        v = f.from_network(float(np.mean(old))) if old and len(old) == len(f.paths) else \
            neutral.get(f.name.split("[")[0], f.value)
        out[f.name] = float(min(max(v, f.low), f.high))
    return out


def _neutral(mechanism) -> dict[str, float]:
    return {p.name: p.neutral for p in mechanism.parameters}


def reaching_off(mechanism, new: Sequence[FreeParameter]) -> list[FreeParameter]:
    """``new`` with each positive (log-scaled) parameter whose neutral value lies below its low bound given that
    bound ``OFF_REACH`` times lower (where the network value stays positive): a mechanism's bounds keep a search
    for its effect in a plausible range, but a likelihood-ratio test needs the extension to reach its parent
    (a sensor lag of 1 s still lags a fast node: its likelihood differs from the lag-free model's)."""
    neutral, out = _neutral(mechanism), []
    for f in new:
        off = neutral.get(f.name.split("[")[0])
        if f.log and off is not None and off < f.low and f.network_value(f.low * OFF_REACH) > 0:
            f = dataclasses.replace(f, low=f.low * OFF_REACH)
        out.append(f)
    return out


def select_mechanisms(recording, *, seed: int = 0, alpha: float = 0.01, max_rounds: int = 3,
                      only: Sequence[str] | None = None, hidden_nodes: int = 2, registry=None,
                      progress=None) -> dict:
    """``diagnose --stochastic`` on a machine recording: the ``auto`` baseline calibrated by output error, then
    refined as a stochastic model (one multiplier per calibrated parameter, σ per node, r per channel); each round
    every registered machine mechanism at each of its places (two at most) is fitted with its own parameters
    free and the rest held at the current estimates, from the mechanism's defaults and from where it is switched
    off (:func:`nested_start`; the better end kept). Only a candidate that reaches its parent where switched off
    (within ``NESTED_GAIN``) is nested in it and can be tested: the others are named as ones their parameters cannot
    switch off (the χ² law of the likelihood ratio does not hold for them). The best testable one by likelihood
    is accepted when its LR test passes at ``alpha`` / (testable candidates) (Bonferroni), the LR statistic
    divided by the baseline's misfit (:func:`.fit.misfit_scale`: innovations correlated over hours, as a
    structurally wrong baseline leaves them, count as fewer independent samples). A candidate gaining less than
    ``NESTED_GAIN`` is *nested* (its best fit is the model it extends). A mechanism acting at once (``at_once``:
    the centrifugal growth) is skipped on a record sampled slower than ``FAST_HEATING_S``. The accepted one is
    then refitted with every parameter free, and the next round starts from it. A mechanism's parameters are named ``<mechanism>.<name>``
    in the model (two mechanisms may both declare ``G_W_K``). Returns the report (JSON-ready): ``baseline``,
    ``selection_path`` (per step ``parent_loglik`` and its ``candidates``: mechanism, place, loglik and
    ``off_loglik``, the likelihood where it is switched off), ``findings`` (mechanism, place, parameters, lr, df, p_value), ``rejected``
    (mechanism, reason) and ``verdict``."""
    from scipy.stats import chi2

    from thermodrift.core.errors import InputError
    from thermodrift.core.physics import calibration as cal
    from thermodrift.core.physics.stochastic.building import BuildingMechanism
    from thermodrift.core.physics.stochastic.fit import fit, loglik, misfit_scale

    if registry is None:
        from thermodrift.core import registry as registry_module

        registry = registry_module.default()
    say = progress or (lambda line: None)
    step_s = float(np.median(np.diff(recording.time_s))) if len(recording) > 1 else 0.0
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
            if not why and cls.at_once and step_s > FAST_HEATING_S:
                why = (f"samples {step_s:.0f} s apart: a step within one sample of a speed change cannot be told "
                       f"from the spindle nose's fast heating (minutes); record at {FAST_HEATING_S:.0f} s or faster")
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
                new = reaching_off(cls, new)
                off = {f"{mid}.{k}": v for k, v in nested_start(cls, net, new).items()}
                new = [dataclasses.replace(f, name=f"{mid}.{f.name}") for f in new]
                m2 = NetworkModel(net2, recording, free=[*free, *new], factors=factors, start=current.values)
                frozen = Frozen(m2, current.values)  # a new node's process noise off too, where it has one
                off.update({p.name: p.low for p in frozen.parameters if p.name.startswith("sigma.")})
                e2 = fit(frozen, m2.data, seed=seed, starts=1, information=False, also=[off])
                off_ll = loglik(frozen, m2.data, off)
                fitted.append((mid, options, new, m2, e2, off_ll))
                say(f"  {mid} {options or ''}: loglik {e2.loglik:.1f} (switched off {off_ll:.1f})")
        if not fitted:
            break
        parent = current.loglik
        testable = [c for c in fitted if abs(c[5] - parent) <= NESTED_GAIN]  # reaches its parent switched off
        for other, _o, _n, _m, e, off_ll in sorted(fitted, key=lambda c: c[4].loglik):  # worst first: a
            gain = e.loglik - parent                                                  # mechanism's best place last
            if abs(off_ll - parent) > NESTED_GAIN:
                rejected[other] = (f"cannot be switched off by its parameters (switched off as far as they allow: "
                                   f"{off_ll - parent:+.1f} against the model it extends; fitted {gain:+.1f}): not "
                                   f"nested, so no likelihood-ratio test")
            elif gain < NESTED_GAIN:
                rejected[other] = f"nested: its best fit is the model it extends (log-likelihood {gain:+.2f})"
        if not testable:
            break
        mid, options, new, m2, e2, _ = max(testable, key=lambda c: c[4].loglik)
        df = len(new)
        lr = max(2.0 * (e2.loglik - parent), 0.0)
        scale = misfit_scale(e2) if lr > 0 else 1.0
        p = float(chi2.sf(lr / scale, df))
        level = alpha / len(testable)
        step = {"name": mid, "place": options, "loglik": e2.loglik, "parent_loglik": parent,
                "n_params": current.n_params + df, "lr": lr, "misfit_scale": scale, "lr_robust": lr / scale,
                "df": df, "p_value": p, "level": level, "accepted": p < level,
                "candidates": [{"mechanism": c[0], "place": c[1], "loglik": c[4].loglik, "off_loglik": c[5]}
                               for c in fitted]}
        path.append(step)
        for other, _o, _n, _m, e, off_ll in testable:
            if other != mid and e.loglik - parent >= NESTED_GAIN:
                rejected[other] = f"explains less than {mid} (likelihood)"
        if p >= level:
            if not rejected.get(mid, "").startswith("nested"):
                rejected[mid] = (f"not significant: LR {lr:.1f} on {df} parameter(s), {lr / scale:.1f} after the "
                                 f"baseline's misfit (× 1/{scale:.2g}), p = {p:.3g} ≥ {level:.3g}")
            break
        rejected.pop(mid, None)
        m2 = NetworkModel(m2.network, recording, free=[*free, *new], factors=factors,
                          start={**current.values, **e2.values})
        current = fit(m2, m2.data, seed=seed, starts=1, information=False)
        net, free = m2.network, [*free, *new]
        findings.append({"mechanism": mid, "place": options, "lr": lr, "df": df, "p_value": p,
                         "parameters": {f.name.split(".", 1)[1]: current.values[f.name] for f in new}})
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
