"""Concealed-effect cases that come with the user's own simulation (``diagnose --simulation``).

:func:`make_sim_case` draws a machine, a programme and a hall like :func:`independent.make_case`, but with every
driver active in every case (spindle, part cycles with cutting power, X axis motion in runs and stops, a
cycling tank chiller on a motor jacket, a lively hall with daily and HVAC cycles), so a varying channel says
nothing about which mechanism is missing. It plants one mechanism (or none) and returns the recording with
the user's simulation of it:

- the same drawn machine without the concealed mechanism (for ``coolant_coupling``: without its jacket; the
  machine's own jacket otherwise stays, as a simulation of a cooled spindle has it);
- every physical parameter (heat capacity and air exposure per part, each joint and conduction link, floor
  contact, each heat source, each part's expansion weight, the jacket) off by its own lognormal factor
  exp(N(0, ``error``));
- with ``structural``: a coarser model, the fd machine as 3/3/2/2/2 volumes per part and the lumped one with
  bodies merged further (2/2/1/1/1);
- driven by the recorded inputs (speed, cutting power, feed, hall air, the chiller inlet as it was), sampled
  on the recording's times: the sensor sites' temperatures (°C) and the logged drift channels (µm).

Seeds: :func:`independent.case_list` (development < 1000, sealed ≥ 1000); the streams differ from
``make_case``'s (key 38), so these are new cases even on the same seeds. Nothing here imports ``thermodrift``.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd

from . import SENSOR_SITES, Generated, _p2p, _readings, fd_model, planted
from .programme import Chiller, programme, room, sample

MAX_SCALE = {"bearing_heat_law": 2.0, "centrifugal_growth": 8.0}


class Replay:
    """A chiller that replays a recorded inlet temperature (°C per grid step): the user drives their
    simulation with the inlet as it was logged, not with a model of the chiller."""

    def __init__(self, inlet: np.ndarray):
        self.values, self.k = inlet, 0

    def inlet(self) -> float:
        return float(self.values[min(self.k, len(self.values) - 1)])

    def step(self, returned_W: float, hall_degC: float, h: float) -> None:
        self.k += 1


def perturbed(m: fd_model.Machine, rng: np.random.Generator, error: float) -> fd_model.Machine:
    """A copy of ``m`` with every physical parameter × its own exp(N(0, ``error``)) (see the module
    docstring); ``error`` 0 returns an exact copy."""
    out = copy.deepcopy(m)
    if error <= 0:
        return out

    def f(size=None):
        return np.exp(rng.normal(0.0, error, size))

    for seg in out.segments.values():
        out.C[seg.idx] *= f()
        out.g_air[seg.idx] *= f()
        for c in out.drift_w:
            out.drift_w[c][seg.idx] *= f()
    off = -np.triu(out.K, 1)
    factor = np.triu(f(out.K.shape), 1)
    off = off * factor
    K = -(off + off.T)
    K[np.diag_indices_from(K)] = -K.sum(axis=1)
    out.K = K
    out.g_floor = out.g_floor * f()
    out.q_top = {k: v * f() for k, v in out.q_top.items()}
    return out


def make_sim_case(seed: int, hidden: str | None, generator: str = "fd", error: float = 0.2,
                  structural: bool = False, dt_s: float = 120.0, hours: float = 30.0
                  ) -> tuple[Generated, pd.DataFrame]:
    """The recording of ``seed`` with ``hidden`` planted (None: a null case) and the user's simulation of it
    (a frame with ``time_s`` and the simulated channels); see the module docstring."""
    lumped = generator == "lumped"
    h = 15.0 if dt_s >= 15.0 else dt_s
    every = max(int(round(dt_s / h)), 1)
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence([seed, 38]).spawn(10)]
    r_machine, r_prog, r_lively, r_chill, r_sens, r_effect, r_choice, r_err, r_jacket, r_user = streams
    prog = programme(r_prog, hours, h, True, True)
    start_hour = float(r_choice.uniform(0, 24))
    air = room(r_lively, prog.t, True, start_hour)
    floor = float(air.mean() - r_choice.uniform(0.5, 2.0))
    has_x = hidden in ("thermal_tilt", "axis_drive_heat") or r_choice.random() < 0.5
    target = float(r_choice.uniform(0.2, 0.4))
    probe_noise = float(r_sens.uniform(0.05, 0.15))
    chiller0 = Chiller.draw(r_chill, steady=False)
    own_jacket = None if hidden == "coolant_coupling" else planted.Jacket(r_jacket)
    base_parts = [own_jacket] if own_jacket else []
    effect = planted.EFFECTS[hidden](r_effect) if hidden else None
    machine_seed = np.random.SeedSequence([seed, 38, 1])
    machine = fd_model.build(np.random.default_rng(machine_seed), block=bool(effect and effect.block), lumped=lumped)
    plain = fd_model.build(np.random.default_rng(machine_seed), lumped=lumped)

    def run(m, parts, chiller=None):
        return fd_model.simulate(m, prog, air, floor, chiller or copy.deepcopy(chiller0), planted.Composite(*parts))

    base = run(plain, base_parts)
    logged = ["z", "x"] if has_x else ["z"]
    ref = _p2p(base.drift["z"])
    goal = max(target * ref, 10 * probe_noise)
    truth, effect_um = base, {}
    if effect is not None and hidden != "sensor_lag":
        for it in range(4):
            truth = run(machine, [*base_parts, effect])
            effect_um = {c: _p2p(truth.drift[c] - base.drift[c]) for c in logged}
            got = max(effect_um.values())
            if got <= 0 or abs(got / goal - 1) < 0.15 or it == 3:
                break
            cap = MAX_SCALE.get(hidden, np.inf)
            if effect.scale >= cap and got < goal:
                break
            effect.scale = min(effect.scale * float(np.clip(goal / got, 0.2, 5.0)), cap)
    table, manifest, info = _readings(machine if effect else plain, truth, prog, air, every, r_sens, has_x,
                                      probe_noise, effect if hidden == "sensor_lag" else None, True, True, True,
                                      seed, hidden)
    # the user's simulation: the machine without the concealed mechanism, parameters off, maybe coarser
    cells = (fd_model.MERGED if lumped else fd_model.LUMPED) if structural else None
    model = perturbed(fd_model.build(np.random.default_rng(machine_seed), lumped=lumped, cells=cells), r_err, error)
    parts = []
    if own_jacket is not None:
        jacket = copy.deepcopy(own_jacket)
        jacket.g *= float(np.exp(r_user.normal(0.0, error))) if error > 0 else 1.0
        parts.append(jacket)
    sim = run(model, parts, Replay(truth.coolant_in))
    cols = {"time_s": table["time_s"].to_numpy()}
    site = dict(model.info)
    site["column_head"] = model.info["j_head"]
    site["bed"] = model.seg("bed").idx[len(model.info["table"]) // 2]
    for s in SENSOR_SITES:
        if s in table.columns:
            cols[s] = sample(sim.T[:, int(site[SENSOR_SITES[s][0]])], every)
    for c in logged:
        cols[f"disp_{c}_um"] = sample(sim.drift[c], every)
    name = f"{generator}:{hidden or 'none'}:{seed}"
    info.update(target_share=target, untouched_z_p2p_um=ref, probe_noise_um=probe_noise, error=error,
                structural=structural, simulated_inputs=["ambient", *(["coolant_inlet"] if own_jacket else [])])
    share = max(effect_um.values()) / ref if effect_um and ref > 0 else 0.0
    gen = Generated(name.replace(":", "_"), seed, hidden, table, manifest,
                    {f"disp_{c}_um": v for c, v in effect_um.items()}, share, effect.scale if effect else 1.0, info)
    return gen, pd.DataFrame(cols)
