"""Concealed-effect recordings from generators that share no code with the library.

:func:`make_case` draws a machine (:mod:`.fd_model`: a distributed-parameter conduction model, or a lumped
network of another topology per seed), a programme,
a hall and sensors (:mod:`.programme`), plants one mechanism in its own form (:mod:`.planted`) and returns the
recording as a table and a manifest in the public file format (``thermodrift diagnose TABLE --manifest YAML``
reads them). Nothing here imports ``thermodrift``.

Seeds: the development half is seeds 0–999, the sealed half seeds ≥ 1000 (:func:`case_list`); the two are
disjoint by construction, and the sealed half is only run with ``--sealed``.

AMPLITUDE_RULE: per case a share s ~ U(0.2, 0.4) is drawn; the planted effect's peak-to-peak on the logged
drift channels (truth minus the same machine, programme and hall without it; the largest over channels) is
brought to s × the peak-to-peak of the untouched z drift, and at least 10 × the probe noise, by rescaling its
amplitude (up to 4 simulations), within physical ceilings (:data:`MAX_SCALE`: bearing law λ ≤ 2, centrifugal
growth ≤ 8 µm at top speed), where an effect may stay under its share.
``sensor_lag`` changes readings only: its size is the pad time constant.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from . import fd_model, planted
from .programme import Chiller, lagged, pad_sensor, programme, room, sample

HIDDEN = planted.HIDDEN
SEALED_FROM = 1000
NULL_OFFSET = 500
AMPLITUDE_RULE = ("planted peak-to-peak = s × untouched z peak-to-peak, s ~ U(0.2, 0.4) per case, at least "
                  "10 × probe noise, within physical ceilings (centrifugal ≤ 8 µm at top speed, bearing-law mix "
                  "λ ≤ 2); sensor_lag: pad τ 300–1200 s")
# physical ceilings of the amplitude: bearing law λ ≤ 2; centrifugal growth ≤ 8 µm at top speed (HSK spindles at
# 6000–12000 rpm grow 1–8 µm); an effect at its ceiling may stay under its drawn share
MAX_SCALE = {"bearing_heat_law": 2.0, "centrifugal_growth": 8.0}
SENSOR_SITES = {"T_front_bearing": ("housing_fb", 1.0), "T_rear_bearing": ("housing_rb", 0.8),
                "T_motor": ("motor_housing", 0.8), "T_column": ("column_head", 0.6), "T_bed": ("bed", 0.5)}


@dataclass
class Generated:
    """One recording: table (time_s and channels), manifest, and the truth needed to score a diagnosis."""

    name: str
    seed: int
    hidden: str | None
    table: pd.DataFrame
    manifest: dict
    effect_um: dict[str, float] = field(default_factory=dict)   # planted peak-to-peak per drift column
    share: float = 0.0                  # achieved effect / untouched z peak-to-peak
    scale: float = 1.0
    info: dict = field(default_factory=dict)

    @property
    def drift_channel(self) -> str:
        """The drift column where the planted effect is largest (z for nulls and sensor lag)."""
        if not self.effect_um or max(self.effect_um.values()) <= 0:
            return "disp_z_um"
        return max(self.effect_um, key=self.effect_um.get)

    def write(self, folder: Path) -> tuple[Path, Path]:
        folder.mkdir(parents=True, exist_ok=True)
        table, man = folder / f"{self.name}.csv", folder / f"{self.name}.yaml"
        self.table.to_csv(table, index=False, float_format="%.4f")
        man.write_text(yaml.safe_dump(self.manifest, sort_keys=False), encoding="utf-8")
        return table, man


def case_list(sealed: bool, per_mechanism: int, nulls: int,
              base: int | None = None) -> list[tuple[int, str | None, bool]]:
    """(seed, hidden, constant drivers) of the development (seeds < 1000) or sealed (≥ 1000) half: hidden
    mechanisms in turn, then nulls (every second with constant coolant, cutting and feed channels). ``base``
    (a multiple of 1000, ≥ 1000) starts another sealed range, never run before."""
    if base is None:
        base = SEALED_FROM if sealed else 0
    out: list[tuple[int, str | None, bool]] = []
    for i in range(per_mechanism * len(HIDDEN)):
        out.append((base + i, HIDDEN[i % len(HIDDEN)], False))
    for i in range(nulls):
        out.append((base + NULL_OFFSET + i, None, i % 2 == 1))
    return out


def _p2p(x: np.ndarray) -> float:
    return float(np.ptp(x)) if len(x) else 0.0


GENERATORS = ("fd", "lumped")


def make_case(seed: int, hidden: str | None, dt_s: float = 120.0, hours: float = 30.0,
              constant_drivers: bool = False, generator: str = "fd") -> Generated:
    """The recording of ``seed`` with ``hidden`` planted (None: a null case); see the module docstring.
    ``generator``: ``fd`` the distributed-parameter machine (64–70 finite volumes), ``lumped`` a lumped
    network of 14–15 nodes with a topology drawn per seed (:func:`fd_model.build`)."""
    if generator not in GENERATORS:
        raise ValueError(f"unknown generator {generator!r}; use one of {', '.join(GENERATORS)}")
    lumped = generator == "lumped"
    if hidden is not None and hidden not in planted.EFFECTS:
        raise ValueError(f"unknown mechanism {hidden!r}; use one of {', '.join(HIDDEN)}")
    h = 15.0 if dt_s >= 15.0 else dt_s
    every = max(int(round(dt_s / h)), 1)
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence([seed, 23]).spawn(8)]
    r_machine, r_prog, r_quiet, r_lively, r_chill, r_sens, r_effect, r_choice = streams
    prog = programme(r_prog, hours, h, hidden == "cutting_heat", hidden == "axis_drive_heat")
    start_hour = float(r_choice.uniform(0, 24))
    quiet = room(r_quiet, prog.t, False, start_hour)
    lively = room(r_lively, prog.t, True, start_hour)
    floor = float(quiet.mean() - r_choice.uniform(0.5, 2.0))
    has_x = hidden in ("thermal_tilt", "axis_drive_heat") or r_choice.random() < 0.4
    steady_coolant = constant_drivers or (hidden != "coolant_coupling" and r_choice.random() < 0.25)
    target = float(r_choice.uniform(0.2, 0.4))
    probe_noise = float(r_sens.uniform(0.05, 0.15))
    chiller0 = Chiller.draw(r_chill, steady=hidden != "coolant_coupling")
    base_parts = [planted.Jacket(np.random.default_rng([seed, 5]))] if steady_coolant else []
    effect = planted.EFFECTS[hidden](r_effect) if hidden else None
    machine = fd_model.build(r_machine, block=bool(effect and effect.block), lumped=lumped)
    plain = fd_model.build(np.random.default_rng(np.random.SeedSequence([seed, 23]).spawn(8)[0]), lumped=lumped)
    cooled = hidden == "coolant_coupling" or steady_coolant

    def run(m, parts, air):
        chiller = copy.deepcopy(chiller0) if cooled else None
        return fd_model.simulate(m, prog, air, floor, chiller, planted.Composite(*parts))

    base = run(plain, base_parts, quiet)
    logged = ["z", "x"] if has_x else ["z"]
    ref = _p2p(base.drift["z"])
    goal = max(target * ref, 10 * probe_noise)
    truth, effect_um = base, {}
    if effect is not None and hidden != "sensor_lag":
        for it in range(4):
            air = quiet + min(effect.scale, 1.0) * (lively - quiet) if hidden == "ambient_coupling" else quiet
            truth = run(machine, [*base_parts, effect], air)
            effect_um = {c: _p2p(truth.drift[c] - base.drift[c]) for c in logged}
            got = max(effect_um.values())
            if got <= 0 or abs(got / goal - 1) < 0.15 or it == 3:
                break
            cap = MAX_SCALE.get(hidden, np.inf)
            if effect.scale >= cap and got < goal:
                break  # the largest this mechanism physically gets
            effect.scale = min(effect.scale * float(np.clip(goal / got, 0.2, 5.0)), cap)
    air_true = quiet + min(effect.scale, 1.0) * (lively - quiet) if hidden == "ambient_coupling" else quiet
    table, manifest, info = _readings(machine if effect else plain, truth, prog, air_true, every, r_sens, has_x,
                                      probe_noise, effect if hidden == "sensor_lag" else None, cooled,
                                      hidden == "cutting_heat" or constant_drivers,
                                      hidden == "axis_drive_heat" or constant_drivers, seed, hidden)
    name = f"{generator}:{hidden or 'none'}:{seed}"
    info.update(target_share=target, untouched_z_p2p_um=ref, probe_noise_um=probe_noise, steady_coolant=steady_coolant)
    share = max(effect_um.values()) / ref if effect_um and ref > 0 else 0.0
    return Generated(name.replace(":", "_"), seed, hidden, table, manifest,
                     {f"disp_{c}_um": v for c, v in effect_um.items()}, share,
                     effect.scale if effect else 1.0, info)


def _readings(m, res, prog, air, every, rng, has_x, probe_noise, pads, cooled, log_cut, log_feed, seed, hidden):
    """Logged table and manifest: surface sensors (offset ±0.3 K, noise 0.01–0.03 K, lag 5–40 s, 0.01 K
    steps, 1–5 % drop towards the air), hall air, coolant inlet, averaged cutting power and feed, probes."""
    T = res.T
    site = dict(m.info)
    site["column_head"] = m.info["j_head"]
    site["bed"] = m.seg("bed").idx[len(m.info["table"]) // 2]
    chosen = [s for s, (_, p) in SENSOR_SITES.items() if rng.random() < p]
    for s in SENSOR_SITES:
        if len(chosen) >= 3:
            break
        if s not in chosen:
            chosen.append(s)
    padded = set()
    if pads is not None:
        k = max(2, int(round(pads.share * len(chosen))))
        padded = set(rng.choice(chosen, size=min(k, len(chosen)), replace=False).tolist())
    cols: dict[str, np.ndarray] = {"time_s": prog.t[::every], "spindle_rpm": sample(prog.speed, every)}
    channels: dict[str, dict] = {"spindle_rpm": {"role": "speed", "unit": "rpm"}}
    for s in SENSOR_SITES:
        if s not in chosen:
            continue
        node = int(site[SENSOR_SITES[s][0]])
        surface = T[:, node] - rng.uniform(0.01, 0.05) * (T[:, node] - air)
        tau = rng.uniform(5.0, 40.0)
        read = pad_sensor(surface, air, pads.tau, pads.air, prog.h) if s in padded else lagged(surface, tau, prog.h)
        v = sample(read, every) + rng.uniform(-0.3, 0.3) + rng.normal(0, rng.uniform(0.01, 0.03), len(cols["time_s"]))
        cols[s] = np.round(v, 2)
        channels[s] = {"role": "temperature", "unit": "degC", "location": SENSOR_SITES[s][0]}
    n = len(cols["time_s"])
    amb = sample(lagged(air, rng.uniform(60.0, 240.0), prog.h), every)
    cols["ambient_degC"] = np.round(amb + rng.uniform(-0.2, 0.2) + rng.normal(0, 0.02, n), 2)
    channels["ambient_degC"] = {"role": "ambient", "unit": "degC"}
    if cooled:
        cin = sample(lagged(res.coolant_in, 10.0, prog.h), every)
        cols["coolant_inlet_degC"] = np.round(cin + rng.uniform(-0.2, 0.2) + rng.normal(0, 0.02, n), 2)
        channels["coolant_inlet_degC"] = {"role": "coolant_inlet", "unit": "degC"}
    if log_cut:
        cols["cutting_power_W"] = np.round(sample(prog.cutting_W, every, mean=True), 1)
        channels["cutting_power_W"] = {"role": "cutting_power", "unit": "W"}
    if log_feed:
        cols["x_feed_mm_min"] = np.round(sample(prog.feed, every, mean=True), 1)
        channels["x_feed_mm_min"] = {"role": "axis_velocity", "unit": "mm_min"}
    for c in (["z", "x"] if has_x else ["z"]):
        v = sample(res.drift[c], every) + rng.uniform(-20, 20) + rng.normal(0, probe_noise, n)
        cols[f"disp_{c}_um"] = np.round(v, 2)
        channels[f"disp_{c}_um"] = {"role": "displacement", "unit": "um", "axis": c}
    manifest = {"description": f"independent distributed-parameter generator, seed {seed}, "
                               f"{'hidden ' + hidden if hidden else 'null'}",
                "time": "time_s", "channels": channels}
    info = {"sensors": chosen, "padded": sorted(padded), "nodes": m.size, "extra_links": m.info.get("extra_links")}
    return pd.DataFrame(cols), manifest, info
