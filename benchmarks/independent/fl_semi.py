"""Semi-synthetic FL_THERMAL: three effects planted in the real recording, each 2–4 µm, in their own forms.

- ``centrifugal_growth``: c·(n/n_max)² through a 20–60 s lag at the real speed changes, on the axial (z)
  channels; c ~ U(2, 4) µm.
- ``ambient_coupling``: a synthetic hall-air channel (daily cycle, HVAC thermostat, heating schedule; see
  :func:`programme.room`) added and declared ``ambient``; the drift channels get its response through an
  unmeasured structure, a first-order lag of 1.5–3 h, peak-to-peak U(2, 4) µm drawn per channel.
- ``coolant_coupling``: a synthetic chiller-inlet channel (:class:`programme.Chiller`, on/off hysteresis, its
  load the spindle's heat ∝ (n/n_max)^1.5 at the real speeds) added and declared ``coolant_inlet``; the drift
  channels get its response through the jacket, a lag of 10–30 min, peak-to-peak U(2, 4) µm per channel.

Each case comes with its control: the same added channel without the response (for centrifugal growth the
plain recording), so a finding counts only where the control does not already name the mechanism.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .programme import Chiller, lagged, room

MECHANISMS = ("centrifugal_growth", "ambient_coupling", "coolant_coupling")


@dataclass
class SemiCase:
    """Channels to add (column -> (role, unit, values)) and drift to add (column -> µm) to the recording;
    ``amplitude_um`` the (median) peak-to-peak of the added drift."""

    mechanism: str
    added: dict[str, tuple[str, str, np.ndarray]] = field(default_factory=dict)
    drift: dict[str, np.ndarray] = field(default_factory=dict)
    amplitude_um: float = 0.0


def _shaped(x: np.ndarray, p2p: float) -> np.ndarray:
    x = x - x.mean()
    return x * p2p / max(float(np.ptp(x)), 1e-12)


def plant(time_s: np.ndarray, speed: np.ndarray, drift_cols: list[str], z_cols: list[str],
          seed: int) -> list[SemiCase]:
    """The three planted cases of ``seed`` for a recording with these times (s), speeds (rpm) and drift
    columns (``z_cols`` the axial ones)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 29]))
    h = float(np.median(np.diff(time_s)))
    r2 = (speed / speed.max()) ** 2
    c = float(rng.uniform(2.0, 4.0))
    cent = SemiCase("centrifugal_growth", amplitude_um=c)
    growth = c * lagged(r2, float(rng.uniform(20.0, 60.0)), h)
    cent.drift = {col: growth for col in (z_cols or drift_cols[:1])}
    out = [cent]
    air = room(rng, time_s - time_s[0], True, float(rng.uniform(0, 24)))
    amb_read = np.round(lagged(air, 120.0, h) + rng.normal(0, 0.02, len(air)), 2)
    amps = rng.uniform(2.0, 4.0, len(drift_cols))
    sign = rng.choice([-1.0, 1.0])
    resp = _shaped(lagged(air, float(rng.uniform(1.5, 3.0)) * 3600.0, h), 1.0)
    out.append(SemiCase("ambient_coupling", {"hall_air_degC": ("ambient", "degC", amb_read)},
                        {col: sign * a * resp for col, a in zip(drift_cols, amps)}, float(np.median(amps))))
    chiller = Chiller.draw(rng, steady=False)
    q0 = float(rng.uniform(600.0, 1400.0))
    inlet = np.empty(len(time_s))
    for k in range(len(time_s)):
        inlet[k] = chiller.inlet()
        chiller.step(q0 * (speed[k] / speed.max()) ** 1.5, float(air[k]), h)
    cin_read = np.round(lagged(inlet, 10.0, h) + rng.normal(0, 0.02, len(inlet)), 2)
    amps = rng.uniform(2.0, 4.0, len(drift_cols))
    sign = rng.choice([-1.0, 1.0])
    resp = _shaped(lagged(inlet, float(rng.uniform(10.0, 30.0)) * 60.0, h), 1.0)
    out.append(SemiCase("coolant_coupling", {"chiller_inlet_degC": ("coolant_inlet", "degC", cin_read)},
                        {col: sign * a * resp for col, a in zip(drift_cols, amps)}, float(np.median(amps))))
    return out


def case_specs(rec, seed: int) -> list[tuple]:
    """The semi-synthetic cases of ``seed`` on an FL_THERMAL recording, in run order: the plain recording, then each
    planting after its control (the plain recording plus the planting's added inputs, when it has any), as
    ``(label, added inputs, planted drift in µm, mechanism or None, control label or None)``."""
    z = [c for c in rec.columns("displacement") if rec.channels[c].meta.get("axis") == "z"]
    specs = [("fl_thermal (plain)", {}, {}, None, None)]
    for case in plant(rec.time_s, rec.speed.to_numpy(dtype=float), rec.columns("displacement"), z, seed):
        control = "fl_thermal (plain)"
        if case.added:
            control = f"fl_thermal + {', '.join(case.added)} (control)"
            specs.append((control, case.added, {}, None, None))
        specs.append((f"fl_thermal + {case.mechanism} ({case.amplitude_um:.1f} um)", case.added, case.drift,
                      case.mechanism, control))
    return specs
