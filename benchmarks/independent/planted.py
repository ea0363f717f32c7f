"""The planted mechanisms, each in its own functional form, as :class:`~fd_model.Effect` hooks.

Every effect has one amplitude ``scale`` (1 = its drawn nominal size) that :mod:`independent` adjusts so the
planted effect has the drawn share of the drift (see ``AMPLITUDE_RULE`` there). The ids are the names the
finder's library uses, so a finding can be scored; the physics is written here from textbook forms:

=========================== ==========================================================================
coolant_coupling            motor jacket, ε-NTU exchanger (ε = 1 − exp(−UA/ṁc_p)) to a tank chiller with
                            on/off hysteresis (:class:`programme.Chiller`)
ambient_coupling            a lively hall (daily + HVAC thermostat cycles + heating schedule) and a draft
                            raising h on column and bed
cutting_heat                a share of the cutting power of part cycles into the spindle nose and table
speed_dependent_convection  rotating-cylinder correlation Nu = 0.133 Re^(2/3) Pr^(1/3) on the nose and a
                            shaft-driven fan on the motor housing, h ∝ (n/n_max)^0.8
bearing_heat_law            bearings ∝ (n/n_max)^p_b with p_b ≠ the motor's p, and an oil viscosity
                            exp(−β ΔT) entering as ν^(2/3)
preload_feedback            bearing heat × (1 + κ·max(ΔT_shaft−housing, 0))^(4/3)
sensor_lag                  sensors on pads: a small mass joined to the surface and the air (τ 5–20 min)
centrifugal_growth          z growth c·(n/n_max)² through its own first-order lag (τ 20–90 s)
slow_structural_mode        an unmeasured headstock block (6 volumes) whose growth acts against z
axis_drive_heat             X screw nut friction ∝ (feed)^e over the screw, servo heat into the bed
thermal_tilt                column bending from the front–back difference: x = ∫ α ΔT/w (y_h − y) dy + lever
=========================== ==========================================================================
"""

from __future__ import annotations

import numpy as np

from .fd_model import CAST_IRON, Effect
from .programme import lagged

HIDDEN = ["ambient_coupling", "coolant_coupling", "cutting_heat", "speed_dependent_convection", "bearing_heat_law",
          "preload_feedback", "sensor_lag", "centrifugal_growth", "slow_structural_mode", "axis_drive_heat",
          "thermal_tilt"]


class Composite(Effect):
    """Several effects at once (a planted one and the machine's own constant-coolant jacket)."""

    def __init__(self, *parts: Effect):
        self.parts = [p for p in parts if p is not None]
        self.block = any(p.block for p in self.parts)

    def setup(self, m, prog):
        for p in self.parts:
            p.setup(m, prog)

    def ambient_g(self, m, n):
        gs = [g for g in (p.ambient_g(m, n) for p in self.parts) if g is not None]
        return sum(gs) if gs else None

    def jacket(self, m):
        js = [j for j in (p.jacket(m) for p in self.parts) if j is not None]
        return js[0] if js else None

    def heat(self, m, T, k, prog):
        qs = [q for q in (p.heat(m, T, k, prog) for p in self.parts) if q is not None]
        return sum(qs) if qs else None

    def drift(self, m, T, prog):
        out: dict[str, np.ndarray] = {}
        for p in self.parts:
            for c, v in p.drift(m, T, prog).items():
                out[c] = out.get(c, 0.0) + v
        return out


class Jacket(Effect):
    """Motor cooling jacket: ṁc_p 80–300 W/K, UA 15–60 W/K, ε-NTU effective conductance ×``scale``."""

    def __init__(self, rng):
        mcp, ua = rng.uniform(80.0, 300.0), rng.uniform(15.0, 60.0)
        self.g = mcp * (1 - np.exp(-ua / mcp))
        self.scale = 1.0

    def jacket(self, m):
        w = np.zeros(m.size)
        w[m.info["jacket"]] = 1.0 / len(m.info["jacket"])
        return w, self.g * self.scale


class Draft(Effect):
    """HVAC draft on column and bed: h_draft 2–6 W/m²K × ``scale`` on their exposed surfaces; the hall's
    lively air (drawn with the case) enters as quiet + min(scale, 1)·(lively − quiet)."""

    def __init__(self, rng):
        self.h = rng.uniform(2.0, 6.0)
        self.scale = 1.0

    def ambient_g(self, m, n):
        g = np.zeros(m.size)
        for s in ("column_front", "column_back", "bed"):
            seg = m.seg(s)
            g[seg.idx] = self.h * self.scale * seg.perimeter * seg.dx
        return g


class CuttingHeat(Effect):
    """A share f (2–6 % × ``scale``) of the cutting power enters the machine: 30–60 % of it at the spindle
    nose (tool and holder), the rest into the table through the part."""

    def __init__(self, rng):
        self.f, self.tool = rng.uniform(0.02, 0.06), rng.uniform(0.3, 0.6)
        self.scale = 1.0

    def heat(self, m, T, k, prog):
        p = prog.cutting_W[k] * self.f * self.scale
        if p == 0:
            return None
        q = np.zeros(m.size)
        q[m.info["nose"]] += p * self.tool / len(m.info["nose"])
        q[m.info["table"]] += p * (1 - self.tool) / len(m.info["table"])
        return q


class RotatingConvection(Effect):
    """Forced convection that grows with speed: a rotating cylinder (Nu = 0.133 Re^(2/3) Pr^(1/3), Re = ωD²/ν)
    on the exposed nose and a shaft-driven fan over the motor housing, h_fan = h₀ (n/n_max)^0.8
    (h₀ 10–30 W/m²K), both × ``scale``."""

    NU_AIR, K_AIR, PR = 1.6e-5, 0.026, 0.71

    def __init__(self, rng):
        self.h_fan = rng.uniform(10.0, 30.0)
        self.scale = 1.0

    def ambient_g(self, m, n):
        g = np.zeros(m.size)
        if n <= 0:
            return g
        d = 2 * m.info["r_s"]
        re = (2 * np.pi * n / 60.0) * d ** 2 / self.NU_AIR
        h_rot = 0.133 * re ** (2 / 3) * self.PR ** (1 / 3) * self.K_AIR / d
        shaft, hs = m.seg("shaft"), m.seg("housing")
        g[m.info["nose"]] = h_rot * np.pi * d * shaft.dx
        perim = 2 * np.pi * np.sqrt(hs.area / np.pi + (m.info["r_s"] + 0.03) ** 2)
        g[m.info["stator"]] += self.h_fan * (n / m.info["n_max"]) ** 0.8 * perim * hs.dx
        return g * self.scale


class BearingLaw(Effect):
    """The bearings follow (n/n_max)^p_b (p_b = p ± 0.5–0.8) times ν(T)^(2/3)/ν₀^(2/3) with
    ν = ν₀ exp(−β(T_bearing − T_start)), β 0.02–0.04 /K, instead of the motor's (n/n_max)^p; heat at top
    speed and start temperature unchanged. ``scale`` λ ≤ 2: heat = old + λ·(new − old), kept ≥ 0 (λ > 1
    carries the law's difference further)."""

    def __init__(self, rng):
        self.shift = rng.uniform(0.5, 0.8) * rng.choice([-1.0, 1.0])
        self.beta = rng.uniform(0.02, 0.04)
        self.scale = 1.0

    def setup(self, m, prog):
        self.pb = float(np.clip(m.p + self.shift, 0.8, 2.6))
        if abs(self.pb - m.p) < 0.4:
            self.pb = m.p - self.shift
        self.t0 = None

    def heat(self, m, T, k, prog):
        n = prog.speed[k]
        if n <= 0:
            return None
        if self.t0 is None:
            self.t0 = T.copy()
        r = n / m.info["n_max"]
        q = np.zeros(m.size)
        for key in ("front_bearing", "rear_bearing"):
            top = m.q_top[key]
            nodes = np.flatnonzero(top)
            visc = np.exp(-self.beta * (T[nodes].mean() - self.t0[nodes].mean())) ** (2 / 3)
            lam = min(self.scale, 2.0)
            q[nodes] = top[nodes] * max(lam * (r ** self.pb * visc - r ** m.p), -r ** m.p)  # heat stays ≥ 0
        return q


class Preload(Effect):
    """Thermal preload: the shaft warming past the housing at a bearing raises the preload and with it the
    friction, heat × (1 + κ·max(ΔT − ΔT_start, 0))^(4/3), κ 0.04–0.1 /K × ``scale``, the factor at most
    :data:`MAX_FACTOR` (beyond it the feedback runs away and the bearing seizes: no machine logs that)."""

    MAX_FACTOR = 3.0

    def __init__(self, rng):
        self.kappa = rng.uniform(0.04, 0.1)
        self.scale = 1.0

    def setup(self, m, prog):
        self.t0 = None

    def heat(self, m, T, k, prog):
        n = prog.speed[k]
        if self.t0 is None:
            self.t0 = T.copy()
        if n <= 0:
            return None
        r = (n / m.info["n_max"]) ** m.p
        q = np.zeros(m.size)
        for key, s, h in (("front_bearing", "front_bearing", "housing_fb"), ("rear_bearing", "rear_bearing",
                                                                             "housing_rb")):
            i, j = m.info[s], m.info[h]
            dT = max((T[i] - T[j]) - (self.t0[i] - self.t0[j]), 0.0)
            top = m.q_top[key]
            q += top * r * (min((1 + self.kappa * self.scale * dT) ** (4 / 3), self.MAX_FACTOR) - 1)
        return q


class SensorPads(Effect):
    """Sensors on pads (magnet on paint): τ 300–1200 s, 2–8 % of the pad's conductance to the air; no effect
    on the machine (applied to the readings by :mod:`independent`)."""

    def __init__(self, rng):
        self.tau = rng.uniform(300.0, 1200.0)
        self.air = rng.uniform(0.02, 0.08)
        self.share = rng.uniform(0.5, 1.0)
        self.scale = 1.0


class Centrifugal(Effect):
    """z grows c·(n/n_max)² (c ±1 µm × ``scale``) through a first-order lag of 20–90 s (rotor and bearing
    races settling)."""

    def __init__(self, rng):
        self.c = rng.choice([-1.0, 1.0])
        self.tau = rng.uniform(20.0, 90.0)
        self.scale = 1.0

    def drift(self, m, T, prog):
        r2 = (prog.speed / m.info["n_max"]) ** 2
        return {"z": self.c * self.scale * lagged(r2, self.tau, prog.h)}


class HeadstockBlock(Effect):
    """An unmeasured headstock block (6 volumes, 0.3–0.5 m, τ of hours) warmed through the housing clamp;
    its growth lifts the spindle: z −= α L ΔT_mean × ``scale``."""

    block = True

    def __init__(self, rng):
        self.scale = 1.0

    def drift(self, m, T, prog):
        bk = m.seg("block")
        d = T[:, bk.idx] - T[0, bk.idx]
        return {"z": -CAST_IRON["alpha"] * bk.n * bk.dx * 1e6 * d.mean(axis=1) * self.scale}


class AxisDrive(Effect):
    """X feed drive: nut friction P₀(|v|/10 m/min)^e (P₀ 15–50 W × ``scale``, e 1.2–1.6) spread over the
    screw, support bearing 20 % of it at the fixed end, servo motor 0.6 P₀ |v|/10 m/min into the bed end."""

    def __init__(self, rng):
        self.p0, self.e = rng.uniform(15.0, 50.0), rng.uniform(1.2, 1.6)
        self.scale = 1.0

    def heat(self, m, T, k, prog):
        v = prog.feed[k] / 10000.0
        if v <= 0:
            return None
        sc, bed = m.seg("screw"), m.seg("bed")
        nut = self.p0 * self.scale * v ** self.e
        q = np.zeros(m.size)
        q[sc.idx] = nut / sc.n
        q[sc.idx[0]] += 0.2 * nut
        q[bed.idx[0]] += 0.6 * self.p0 * self.scale * v
        return q


class ColumnBending(Effect):
    """Column bending from its front–back difference: curvature α(T_front − T_back)/w, x at the head =
    ∫₀^{y_h} κ (y_h − y) dy plus the head's lever (0.3–0.5 m) × slope, × ``scale``."""

    def __init__(self, rng):
        self.lever = rng.uniform(0.3, 0.5)
        self.scale = 1.0

    def drift(self, m, T, prog):
        cf, cb = m.seg("column_front"), m.seg("column_back")
        d = (T[:, cf.idx] - T[0, cf.idx]) - (T[:, cb.idx] - T[0, cb.idx])
        y = cf.x
        below = y <= m.info["y_head"]
        kappa = CAST_IRON["alpha"] * d[:, below] / m.info["w_col"]
        x = (kappa * (m.info["y_head"] - y[below] + self.lever) * cf.dx).sum(axis=1) * 1e6
        return {"x": x * self.scale}


EFFECTS = {"coolant_coupling": Jacket, "ambient_coupling": Draft, "cutting_heat": CuttingHeat,
           "speed_dependent_convection": RotatingConvection, "bearing_heat_law": BearingLaw,
           "preload_feedback": Preload, "sensor_lag": SensorPads, "centrifugal_growth": Centrifugal,
           "slow_structural_mode": HeadstockBlock, "axis_drive_heat": AxisDrive, "thermal_tilt": ColumnBending}
assert set(EFFECTS) == set(HIDDEN)
