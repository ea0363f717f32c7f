"""The user's simulation as a table: read it, check it, put it on the recording's times; or make it from a network.

A simulation table (CSV, Parquet or XLSX) holds the recording manifest's time column (same unit) and any
subset of the recording's temperature and displacement channels, with the same names and units (°C, µm;
other units the manifest allows are converted like the recording's), on the same or a finer time base.
Columns that are not such a channel are ignored; at least one displacement channel is needed. The values are
interpolated linearly onto the recording's times (:func:`align`). A simulation that starts after the
recording, ends before it, has a time outside it, a step coarser than the recording's or a missing value
is refused with one line (:class:`~thermodrift.core.errors.InputError`, exit code 2 on the command line).

:func:`drive` runs a thermodrift network on a recording's own inputs (speed, ambient, coolant inlet, cutting
power, axis velocity), which is what ``thermodrift simulate --network spec.yaml --drive TABLE --manifest
M.yaml --out SIM.csv`` writes.
"""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from thermodrift.core.errors import InputError

KINDS = ("temperature", "displacement")
# a simulation sample may sit this share of the recording's step outside the recording (rounding of times)
TIME_TOLERANCE = 0.01


def simulated_channels(recording) -> list[str]:
    """The recording's channels a simulation can give: its temperature and displacement channels."""
    return [c for c in recording.channels if recording.channels[c].role in KINDS]


def _header(path: Path, sheet: str | None) -> list[str]:
    suffix = path.suffix.lower()
    try:
        if suffix == ".csv":
            return [str(c).strip() for c in pd.read_csv(path, nrows=0).columns]
        if suffix == ".parquet":
            import pyarrow.parquet as pq

            return [str(c).strip() for c in pq.read_schema(path).names]
        if suffix == ".xlsx":
            return [str(c).strip() for c in pd.read_excel(path, sheet_name=sheet or 0, nrows=0).columns]
    except (OSError, ValueError, ImportError) as exc:
        raise InputError(f"cannot read the simulation table ({type(exc).__name__})", file=str(path),
                         hint="write it as CSV, Parquet or XLSX with a header row") from None
    raise InputError(f"unknown table format {suffix!r}", file=str(path), hint="use .csv, .parquet or .xlsx")


def read_simulation(path: str | Path, recording, manifest_path: str | Path) -> pd.DataFrame:
    """The simulation table at ``path`` as a frame indexed by time (s), its columns the recording's
    temperature (°C) and displacement (µm) channels it holds; read with the recording's manifest (time
    column and unit, each channel's unit), so every check of :func:`thermodrift.core.recording.load_recording`
    applies. Not yet on the recording's times: :func:`align` does that."""
    from thermodrift.core.recording import load_recording
    from thermodrift.core.recording.loading import read_manifest

    path = Path(path)
    if not path.is_file():
        raise InputError("simulation table not found", file=str(path), hint="check the path given to --simulation")
    man = read_manifest(manifest_path, ())
    header = _header(path, man.sheet)
    if man.time not in header:
        raise InputError(f"no time column {man.time!r}", file=str(path),
                         hint="the simulation table needs the recording manifest's time column, in its unit")
    wanted = set(simulated_channels(recording))
    spec = {c: {"role": r, "unit": u, **meta} for c, (r, u, meta) in man.channels.items()
            if c in wanted and c in header}
    if not any(man.channels[c][0] == "displacement" for c in spec):
        raise InputError("no displacement channel of the recording in the simulation table", file=str(path),
                         hint="name the simulated drift columns as in the recording: "
                              + ", ".join(c for c in wanted if recording.channels[c].role == "displacement"))
    doc = {"time": man.time, **({"time_unit": man.time_unit} if man.time_unit else {}),
           **({"sheet": man.sheet} if man.sheet else {}), "channels": spec}
    with tempfile.TemporaryDirectory(prefix="thermodrift-sim-") as tmp:
        m = Path(tmp) / "simulation.manifest.yaml"
        m.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
        sim = load_recording(path, m, require=())
    gaps = [n for n in sim.notes if "interpolated" in n]
    if gaps:
        raise InputError(f"missing values in the simulation ({gaps[0]})", file=str(path),
                         hint="a simulation has a value at every time it gives")
    return sim.data[list(spec)]


def align(simulation: pd.DataFrame, recording, source: str = "simulation") -> pd.DataFrame:
    """``simulation`` (indexed by time in s, or with a ``time_s`` column; columns the recording's temperature
    and displacement channels) interpolated linearly onto the recording's times. InputError when it does not
    cover the recording, has a time outside it, a step coarser than the recording's, a missing value or no
    displacement channel of the recording."""
    sim = simulation.set_index("time_s") if "time_s" in simulation.columns else simulation
    t_sim = np.asarray(sim.index, dtype=float)
    t = recording.time_s
    step = float(np.median(np.diff(t)))
    tol = TIME_TOLERANCE * step
    wanted = simulated_channels(recording)
    cols = [c for c in sim.columns if c in wanted]
    if not any(recording.channels[c].role == "displacement" for c in cols):
        raise InputError(f"{source}: no displacement channel of the recording",
                         hint="name the simulated drift columns as in the recording")
    if len(t_sim) < 2 or np.any(np.diff(t_sim) <= 0):
        raise InputError(f"{source}: times must increase", hint="sort the simulation by time, one row per time")
    outside = np.flatnonzero((t_sim < t[0] - tol) | (t_sim > t[-1] + tol))
    if len(outside):
        raise InputError(f"{source}: time {t_sim[outside[0]]:g} s lies outside the recording "
                         f"({t[0]:g}–{t[-1]:g} s)", row=int(outside[0]) + 2,
                         hint="simulate exactly the recording's time span")
    if t_sim[0] > t[0] + tol or t_sim[-1] < t[-1] - tol:
        raise InputError(f"{source}: covers {t_sim[0]:g}–{t_sim[-1]:g} s, the recording {t[0]:g}–{t[-1]:g} s",
                         hint="simulate the recording's whole time span")
    gap = np.flatnonzero(np.diff(t_sim) > step * (1 + TIME_TOLERANCE) + 1e-9)
    if len(gap):
        i = int(gap[0])
        raise InputError(f"{source}: gap from {t_sim[i]:g} s to {t_sim[i + 1]:g} s, longer than the recording's "
                         f"step of {step:g} s", row=i + 3, hint="simulate on the recording's time base or a finer one")
    values = sim[cols].to_numpy(dtype=float)
    bad = np.argwhere(~np.isfinite(values))
    if len(bad):
        i, j = bad[0]
        raise InputError(f"{source}: missing value at {t_sim[i]:g} s", column=cols[j], row=int(i) + 2,
                         hint="a simulation has a value at every time it gives")
    out = {c: np.interp(t, t_sim, values[:, j]) for j, c in enumerate(cols)}
    return pd.DataFrame(out, index=pd.Index(t, name="time_s"))


def drive(network, recording) -> pd.DataFrame:
    """What ``network``'s sensors read (°C, µm; no noise) with the recording's inputs driving it, on the
    recording's times: one column per sensor, indexed by time (s), not rounded to the sensors' resolution.
    The network starts at rest in equilibrium with the first sample's ambient and coolant."""
    from thermodrift.core.physics.integrate import simulate
    from thermodrift.core.physics.scenarios import Scenario
    from thermodrift.core.physics.sensors import TemperatureSensor

    exact = network.replace(*[dataclasses.replace(s, **({"resolution_K": 0.0} if isinstance(s, TemperatureSensor)
                                                         else {"resolution_um": 0.0})) for s in network.sensors])
    readings = simulate(exact, Scenario.from_recording(recording)).measure(None)
    readings.index = pd.Index(recording.time_s, name="time_s")
    return readings


def write(frame: pd.DataFrame, path: str | Path, time_column: str = "time_s", time_unit: str | None = None) -> Path:
    """Write a simulation frame (indexed by time in s) as CSV, Parquet or XLSX (by suffix), its time column
    named and scaled as the recording manifest's (``time_unit`` None: seconds)."""
    from thermodrift.core.recording.loading import TIME_UNITS

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet", ".xlsx"):
        raise InputError(f"unknown table format {suffix!r}", file=str(path), hint="use .csv, .parquet or .xlsx")
    out = frame.reset_index(drop=True)
    out.insert(0, time_column, np.asarray(frame.index, dtype=float) / TIME_UNITS[time_unit or "s"])
    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".csv":
        out.to_csv(path, index=False, float_format="%.6g")
    elif suffix == ".parquet":
        out.to_parquet(path, index=False)
    else:
        out.to_excel(path, index=False)
    return path
