"""Probe: does the ``auto`` baseline's hidden-node choice depend on where its calibration stops?

``diagnose`` chooses the hidden nodes of the ``auto`` baseline on the inner validation block
(:func:`~thermodrift.core.physics.diagnose.adequacy.choose_hidden`): each set of
:data:`~thermodrift.core.physics.diagnose.adequacy.HIDDEN_OPTIONS` is calibrated on the rows before that block
and scored on it (noise-weighted, temperature and displacement channels balanced). This probe repeats those
calibrations from the declared start and from jittered starts (the calibration's own ``jitter_seed``) and prints,
per start and hidden set, the held-out and the fitted error, the search's stop, and the set the rule in force
would keep if that start had been the declared one. Nothing in the finder changes::

    python benchmarks/probe_hidden_starts.py --jitter-seeds 1 3 4 5 6      # FL_THERMAL from the shared data folder
    python benchmarks/probe_hidden_starts.py --table my.csv --manifest my.yaml --jitter-seeds 1 2
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from thermodrift.core.physics.calibration import calibrate
from thermodrift.core.physics.diagnose import adequacy, final_cut, screening
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.recording import load_recording

HERE = Path(__file__).resolve().parent
FL_TABLE = HERE.parent.parent / "shared" / "data" / "fl_thermal" / "data.xlsx"
FL_MANIFEST = HERE.parent / "plugins" / "datasets" / "fl_thermal.yaml"


def held_out_errors(recording, jitter_seed: int | None, evaluations: int) -> list[dict]:
    """Per hidden set: the held-out and fitted balanced errors (noise units) of the calibration from this start."""
    t = recording.time_s
    fit = t < final_cut(recording)
    inner_mask = fit & (t < final_cut(recording.select(fit)))
    inner, val = np.flatnonzero(inner_mask), np.flatnonzero(fit & ~inner_mask)
    inner_rec, scenario = recording.select(inner_mask), Scenario.from_recording(recording)
    out = []
    for h in adequacy.HIDDEN_OPTIONS:
        cal = calibrate(inner_rec, None, hidden_nodes=h, intervals=False, max_evaluations=evaluations,
                        prior_strength=0.0, jitter_seed=jitter_seed)
        channels = list(cal.sigma)
        kinds = [cal.channel_kind[c] for c in channels]
        sigma = np.array([cal.sigma[c] for c in channels])
        measured = recording.data[channels].to_numpy(dtype=float)
        readings = screening.baseline_of(cal.network, scenario, channels, measured, inner, sigma).readings
        out.append({"hidden": len(h), "held_out": adequacy._balanced_error(measured, readings, sigma, kinds, val),
                    "fitted": adequacy._balanced_error(measured, readings, sigma, kinds, inner), "stop": cal.stop})
    return out


def kept(rows: list[dict]) -> int:
    """The hidden set the rule in force keeps (a larger set must beat the kept one by MIN_GAIN)."""
    best = rows[0]
    for r in rows[1:]:
        if r["held_out"] < (1 - adequacy.MIN_GAIN) * best["held_out"]:
            best = r
    return best["hidden"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--table", type=Path, default=FL_TABLE)
    ap.add_argument("--manifest", type=Path, default=FL_MANIFEST)
    ap.add_argument("--jitter-seeds", nargs="*", type=int, default=[1, 2])
    ap.add_argument("--evaluations", type=int, default=200, help="as diagnose's baseline_evaluations")
    args = ap.parse_args()
    recording = load_recording(args.table, args.manifest)
    print("| start | " + " | ".join(f"{len(h)} hidden: held out / fitted" for h in adequacy.HIDDEN_OPTIONS)
          + " | kept |")
    print("|---|" + "---:|" * (len(adequacy.HIDDEN_OPTIONS) + 1))
    for seed in [None, *args.jitter_seeds]:
        rows = held_out_errors(recording, seed, args.evaluations)
        cells = [f"{r['held_out']:.3g} / {r['fitted']:.5g}" + ("" if r["stop"] == "tolerance" else f" ({r['stop']})")
                 for r in rows]
        print(f"| {'declared' if seed is None else f'jitter {seed}'} | " + " | ".join(cells)
              + f" | {kept(rows)} |", flush=True)


if __name__ == "__main__":
    main()
