"""Houses as linear stochastic differential equations, simulated by Euler–Maruyama: an independent check of
stochastic grey-box identification. Nothing here imports ``thermodrift``.

The structures are the standard RC forms of building heat dynamics (Bacher & Madsen 2011, "Identifying
suitable models for the heat dynamics of buildings", Energy and Buildings 43): the interior ``Ti`` and any of
an interior medium ``Tm``, an envelope ``Te``, a heater ``Th`` and a sensor ``Ts``; with an envelope, ``AeRia``
adds the envelope's solar aperture ``Ae`` and a direct interior–ambient resistance ``Ria``. Names list the
states in the order Ti, Tm, Te, Th, Ts, then AeRia (``TiTeTh``, ``TiTmTeAeRia``).

Units: time h, temperatures °C, resistances K/kW, capacities kWh/K, heat kW, solar irradiance kW/m², apertures
m², process-noise intensities K/√h, measurement noise K. With every state present::

    Ci dTi = [(Tm−Ti)/Rim + (Te−Ti)/Rie + (Th−Ti)/Rih + (Ts−Ti)/Ris + (Ta−Ti)/Ria + Aw Ps] dt + Ci σi dωi
    Cm dTm = (Ti−Tm)/Rim dt + Cm σm dωm
    Ce dTe = [(Ti−Te)/Rie + (Ta−Te)/Rea + Ae Ps] dt + Ce σe dωe
    Ch dTh = [(Ti−Th)/Rih + Φh] dt + Ch σh dωh
    Cs dTs = (Ti−Ts)/Ris dt + Cs σs dωs
    yTi    = Ts + ε,  ε ~ N(0, sd²)

Without ``Th`` the heat Φh enters ``Ti``; without ``Ts`` the output is ``Ti``; without ``Te`` the interior meets
the ambient through ``Ria`` (then ``AeRia`` does not apply); with ``Te`` but without ``AeRia`` there is no
``Ria`` and no ``Ae``.

Simulation: inputs are held over each 15 min sample (row k's Ta, Ps, Thm act on [t_k, t_k+15 min), the
convention of continuous–discrete filtering), and the state is stepped by Euler–Maruyama on a fine step
(default 10 s) — a different numerical route from the exact discretisation an estimator uses. The heating is a
thermostat that reads the measured temperature each sample (on/off with hysteresis, modulated, night set-back).

Seeds: the development half is seeds 0–9999, the sealed half seeds ≥ 10000 (:data:`SEALED_FROM`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

EXTRA = ("Tm", "Te", "Th", "Ts")
ORDER = ("Ti", "Tm", "Te", "Th", "Ts")
SEALED_FROM = 10000
SAMPLE_H = 0.25
MANIFEST = {"time": "t",
            "channels": {"Ta": {"role": "ambient", "unit": "degC"},
                         "Ps": {"role": "solar_irradiance", "unit": "kW/m2"},
                         "Thm": {"role": "heating", "unit": "kW"},
                         "yTi": {"role": "temperature", "unit": "degC"}}}


def structures() -> list[str]:
    """Every structure of the library: Ti with any subset of Tm, Te, Th, Ts; with Te also the AeRia variant."""
    out = []
    for r in range(len(EXTRA) + 1):
        for extra in itertools.combinations(EXTRA, r):
            base = "Ti" + "".join(extra)
            out.append(base)
            if "Te" in extra:
                out.append(base + "AeRia")
    return out


def parse(name: str) -> tuple[tuple[str, ...], bool]:
    """(states in order, AeRia present) of a structure name such as ``TiTeThAeRia``."""
    aeria = name.endswith("AeRia")
    body = name[:-5] if aeria else name
    states = tuple(s for s in ORDER if s in body)
    if "".join(states) != body or not states or states[0] != "Ti" or (aeria and "Te" not in states):
        raise ValueError(f"unknown structure {name!r}; expected one of {structures()}")
    return states, aeria


@dataclass
class House:
    """One drawn house: structure, physical parameters (units in the module docstring) and the thermostat."""

    structure: str
    params: dict[str, float]
    meas_sd: float
    heater_kw: float                    # thermostat's full power, kW
    setpoint: tuple[float, float]       # day, night set-points, °C
    info: dict = field(default_factory=dict)

    @property
    def states(self) -> tuple[str, ...]:
        return parse(self.structure)[0]

    @property
    def htc(self) -> float:
        """Steady-state heat-transfer coefficient interior → ambient, kW/K."""
        p = self.params
        states, aeria = parse(self.structure)
        if "Te" not in states:
            return 1.0 / p["Ria"]
        return 1.0 / (p["Rie"] + p["Rea"]) + (1.0 / p["Ria"] if aeria else 0.0)

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(A, B, sigma, c): dx = (A x + B u) dt + diag(sigma) dω, y = c·x; u = (Ta, Ps, Φh); per hour."""
        p = self.params
        states, aeria = parse(self.structure)
        ix = {s: i for i, s in enumerate(states)}
        n = len(states)
        G = np.zeros((n, n))                    # conductances between states, kW/K
        ga = np.zeros(n)                        # conductance to the ambient
        solar = np.zeros(n)                     # aperture, m²
        heat = np.zeros(n)
        links = {"Tm": "Rim", "Te": "Rie", "Th": "Rih", "Ts": "Ris"}
        for s, r in links.items():
            if s in ix:
                G[0, ix[s]] = G[ix[s], 0] = 1.0 / p[r]
        if "Te" in ix:
            ga[ix["Te"]] = 1.0 / p["Rea"]
            if aeria:
                ga[0] = 1.0 / p["Ria"]
                solar[ix["Te"]] = p["Ae"]
        else:
            ga[0] = 1.0 / p["Ria"]
        solar[0] = p["Aw"]
        heat[ix["Th"] if "Th" in ix else 0] = 1.0
        C = np.array([p["C" + s[1]] for s in states])
        A = (G - np.diag(G.sum(axis=1) + ga)) / C[:, None]
        B = np.column_stack([ga, solar, heat]) / C[:, None]
        sigma = np.array([p["sigma_" + s[1]] for s in states])
        c = np.zeros(n)
        c[ix["Ts"] if "Ts" in ix else 0] = 1.0
        return A, B, sigma, c


def _logu(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def draw_house(structure: str, rng: np.random.Generator) -> House:
    """Parameters around realistic values for a dwelling: HTC 50–400 W/K, time constants hours to days.

    Each added state is drawn so that its effect on the indoor reading is of the order of a kelvin, not
    negligible (a structure nobody could tell apart from its parent is not a test of selection): the interior
    holds 5–20 % of the house's capacity and meets the envelope with a lag of 0.5–3 h (its resistance at most
    half the envelope's), a medium holds 1–5 × the interior's capacity with an exchange lag of 1–6 h, a heater
    lags 0.5–2 h, a sensor 0.3–1 h, the direct interior–ambient path carries 20–50 % of the HTC; the
    apertures are 5–25 m² per kW/K of HTC (1.5–7.5 K of steady gain at 0.3 kW/m²)."""
    states, aeria = parse(structure)
    p: dict[str, float] = {}
    htc = _logu(rng, 0.05, 0.4)                             # kW/K
    tau = _logu(rng, 20.0, 100.0)                           # whole-house time constant, h
    cap = tau * htc                                         # kWh/K
    if "Te" in states:
        share = rng.uniform(0.2, 0.5) if aeria else 0.0
        r_env = 1.0 / ((1.0 - share) * htc)
        p["Ci"] = cap * rng.uniform(0.05, 0.2)
        p["Ce"] = cap - p["Ci"]
        p["Rie"] = min(rng.uniform(0.5, 3.0) / p["Ci"], 0.5 * r_env)     # interior–envelope lag 0.5–3 h
        p["Rea"] = r_env - p["Rie"]
        if aeria:
            p["Ria"] = 1.0 / (share * htc)
            p["Ae"] = htc * rng.uniform(5.0, 25.0)
    else:
        p["Ria"] = 1.0 / htc
        p["Ci"] = cap
    if "Tm" in states:
        ratio = rng.uniform(1.0, 5.0)                                     # the medium holds 1–5 × the air's
        p["Cm"] = p["Ci"] * ratio / (1.0 + ratio)
        p["Ci"] = p["Ci"] / (1.0 + ratio)
        p["Rim"] = rng.uniform(1.0, 6.0) * (p["Ci"] + p["Cm"]) / (p["Ci"] * p["Cm"])   # exchange lag 1–6 h
    p["Aw"] = htc * rng.uniform(5.0, 25.0)         # m²: 1.5–7.5 K of steady gain at 0.3 kW/m²
    heater_kw = htc * rng.uniform(25.0, 35.0)
    if "Th" in states:
        p["Rih"] = rng.uniform(3.0, 8.0) / heater_kw          # heater 3–8 K above the room per kW share
        p["Ch"] = rng.uniform(0.5, 2.0) / p["Rih"]
    if "Ts" in states:
        p["Cs"] = p["Ci"] * rng.uniform(0.02, 0.1)
        p["Ris"] = rng.uniform(0.3, 1.0) / p["Cs"]
    noise = {"i": (0.05, 0.2), "m": (0.02, 0.1), "e": (0.02, 0.1), "h": (0.1, 0.4), "s": (0.02, 0.08)}
    for s in states:
        p["sigma_" + s[1]] = _logu(rng, *noise[s[1]])
    day = rng.uniform(19.5, 21.5)
    return House(structure, p, meas_sd=_logu(rng, 0.01, 0.04), heater_kw=heater_kw,
                 setpoint=(day, day - rng.uniform(2.0, 4.0)))


def weather(n: int, rng: np.random.Generator, start_day: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(Ta °C, Ps kW/m²) over n samples of 15 min in a north-European winter.

    Outdoor: a slow seasonal drift, weather fronts (Ornstein–Uhlenbeck, τ 1.5 d, sd 3 K), a daily cycle of
    1–4 K peaking at 15:00 that is larger on clear days. Solar: a clear-sky bell from 08:30 to 16:30 with a
    peak of 0.15–0.4 kW/m², times a cloud cover per day and a fluctuating within-day transmission."""
    t = np.arange(n) * SAMPLE_H
    days = int(np.ceil(n * SAMPLE_H / 24.0)) + 1
    clear = rng.beta(1.2, 1.8, size=days)                   # 1 = clear sky
    d = (t // 24).astype(int)
    hour = t % 24
    a = np.exp(-SAMPLE_H / 36.0)
    front = np.zeros(n)
    z = rng.standard_normal(n) * 3.0 * np.sqrt(1 - a * a)
    front[0] = rng.normal(0.0, 3.0)
    for k in range(1, n):
        front[k] = a * front[k - 1] + z[k]
    mean = rng.uniform(2.0, 8.0) - rng.uniform(0.0, 4.0) * t / t[-1]
    daily = (1.0 + 3.0 * clear[d]) * np.cos(2 * np.pi * (hour - 15.0) / 24.0) / 2.0
    ta = mean + front + daily + rng.normal(0.0, 0.1, n)
    peak = rng.uniform(0.15, 0.4) * (1.0 + 0.2 * np.cos(2 * np.pi * (t / 24.0 + start_day) / 365.0))
    bell = np.where((hour > 8.5) & (hour < 16.5), np.sin(np.pi * (hour - 8.5) / 8.0), 0.0) ** 1.5
    flick = np.zeros(n)
    e = rng.standard_normal(n) * 0.25
    for k in range(1, n):
        flick[k] = 0.7 * flick[k - 1] + e[k]
    trans = np.clip(0.15 + 0.85 * clear[d] + flick * (1.0 - clear[d]), 0.05, 1.0)
    ps = np.clip(peak * bell * trans, 0.0, 0.4)
    return ta, ps


def simulate(house: House, days: float = 60.0, seed: int = 0, step_s: float = 10.0) -> pd.DataFrame:
    """The recording of one house: columns t (timestamps every 15 min), Ta, Ps, Thm (heat, kW), yTi.

    The state starts at the steady state of the first sample's inputs and the day set-point; the thermostat
    reads yTi each sample: on below set-point − 0.3 K, off above set-point + 0.3 K, power
    heater_kw × clip(0.5 + 0.5 (set-point − yTi), 0.3, 1) while on; set-back from 22:00 to 06:30."""
    rng = np.random.default_rng(seed)
    n = int(round(days * 24.0 / SAMPLE_H))
    ta, ps = weather(n, rng)
    A, B, sigma, c = house.matrices()
    m = int(round(SAMPLE_H * 3600.0 / step_s))
    dt = SAMPLE_H / m
    nx = len(sigma)
    hour = (np.arange(n) * SAMPLE_H) % 24
    sp = np.where((hour >= 6.5) & (hour < 22.0), house.setpoint[0], house.setpoint[1])
    # a steady state with the heat that holds the day set-point
    u0 = np.array([ta[0], 0.0, 0.0])
    x = np.linalg.solve(A, -B @ u0)
    x = x + (house.setpoint[0] - c @ x)
    eps = rng.normal(0.0, house.meas_sd, n)
    y = np.empty(n)
    heat = np.empty(n)
    on = False
    I = np.eye(nx) + dt * A
    for k in range(n):
        y[k] = c @ x + eps[k]
        if y[k] < sp[k] - 0.3:
            on = True
        elif y[k] > sp[k] + 0.3:
            on = False
        heat[k] = house.heater_kw * float(np.clip(0.5 + 0.5 * (sp[k] - y[k]), 0.3, 1.0)) if on else 0.0
        drive = dt * (B @ np.array([ta[k], ps[k], heat[k]]))
        w = rng.standard_normal((m, nx)) * (sigma * np.sqrt(dt))
        for j in range(m):
            x = I @ x + drive + w[j]
    t = pd.date_range("2021-11-01", periods=n, freq="15min")
    return pd.DataFrame({"t": t, "Ta": ta, "Ps": ps, "Thm": heat, "yTi": y})


def case_list(sealed: bool, cases: int, base: int = 0) -> list[tuple[int, str]]:
    """(seed, structure) of ``cases`` houses cycling through :func:`structures`, from the development half
    (seeds from ``base``) or the sealed half (seeds from SEALED_FROM + base)."""
    names = structures()
    start = (SEALED_FROM if sealed else 0) + base
    return [(start + i, names[i % len(names)]) for i in range(cases)]


def make_case(seed: int, structure: str, days: float = 60.0, step_s: float = 10.0) -> tuple[House, pd.DataFrame]:
    """A drawn house of the given structure and its recording, both from ``seed``."""
    rng = np.random.default_rng([seed, 1])
    house = draw_house(structure, rng)
    return house, simulate(house, days=days, seed=seed, step_s=step_s)
