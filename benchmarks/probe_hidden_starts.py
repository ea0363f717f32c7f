"""Probe: does the ``auto`` baseline's hidden-node choice depend on where its calibration stops?

``diagnose`` chooses the hidden nodes of the ``auto`` baseline on the inner validation block
(:func:`~thermodrift.core.physics.diagnose.adequacy.choose_hidden`): each set of
:data:`~thermodrift.core.physics.diagnose.adequacy.HIDDEN_OPTIONS` is calibrated on the rows before that block
and scored on it (noise-weighted, temperature and displacement channels balanced). This probe repeats those
calibrations from the declared start and from jittered starts (the calibration's own ``jitter_seed``) and prints,
per start and hidden set, the held-out and the fitted error and the set the rule in force would keep if that start
had been the declared one (``choose_hidden`` with the start's ``jitter_seed``). Nothing in the finder changes::

    python benchmarks/probe_hidden_starts.py --jitter-seeds 1 3 4 5 6      # FL_THERMAL from the shared data folder
    python benchmarks/probe_hidden_starts.py --table my.csv --manifest my.yaml --jitter-seeds 1 2
    python benchmarks/probe_hidden_starts.py --independent fd     # the development half of an independent generator

With ``--independent`` it runs the development half of that generator (``benchmarks/independent``: 11 hidden-mechanism
cases and 20 nulls) and prints, per case, the set kept from the declared start and from jitter seed 1 and the ratio
of the two starts' held-out errors of the set kept from the declared start.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from thermodrift.core.physics.diagnose import adequacy, inner_split, screening
from thermodrift.core.physics.scenarios import Scenario
from thermodrift.core.recording import load_recording

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import independent  # noqa: E402 - the independent generators next to this script
FL_TABLE = HERE.parent.parent / "shared" / "data" / "fl_thermal" / "data.xlsx"
FL_MANIFEST = HERE.parent / "plugins" / "datasets" / "fl_thermal.yaml"


def hidden_table(recording, jitter_seed: int | None, evaluations: int) -> tuple[int, list[dict]]:
    """The hidden-node count the adequacy step keeps and its table (held-out and fitted error per set, noise units)
    when every calibration starts from ``jitter_seed`` (None: the declared start), on diagnose's inner split."""
    fit, inner_mask = inner_split(recording)
    inner, val = np.flatnonzero(inner_mask), np.flatnonzero(fit & ~inner_mask)
    hidden, table, _ = adequacy.choose_hidden(recording, inner, val, Scenario.from_recording(recording), evaluations,
                                              screening.baseline_of, jitter_seed=jitter_seed)
    return len(hidden), table


def independent_half(generator: str, evaluations: int) -> None:
    """The development half of ``generator``: the set kept from the declared start and from jitter seed 1, and the
    spread of the declared set's held-out error over the two starts."""
    print("| case | kept (declared) | kept (jitter 1) | held-out error, jitter 1 / declared (set kept) |")
    print("|---|---:|---:|---:|")
    for seed, hidden, constant in independent.case_list(False, 1, 20):
        gen = independent.make_case(seed, hidden, constant_drivers=constant, generator=generator)
        with tempfile.TemporaryDirectory() as folder:
            recording = load_recording(*gen.write(Path(folder)))
        (k, declared), (k_jittered, jittered) = (hidden_table(recording, s, evaluations) for s in (None, 1))
        i = [r["hidden_nodes"] for r in declared].index(k)
        print(f"| {gen.name} | {k} | {k_jittered} | "
              f"{jittered[i]['heldout_error'] / declared[i]['heldout_error']:.2f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--table", type=Path, default=FL_TABLE)
    ap.add_argument("--manifest", type=Path, default=FL_MANIFEST)
    ap.add_argument("--jitter-seeds", nargs="*", type=int, default=[1, 2])
    ap.add_argument("--evaluations", type=int, default=200, help="as diagnose's baseline_evaluations")
    ap.add_argument("--independent", choices=sorted(independent.GENERATORS),
                    help="run the development half of this independent generator instead of one recording")
    args = ap.parse_args()
    if args.independent:
        independent_half(args.independent, args.evaluations)
        return
    recording = load_recording(args.table, args.manifest)
    print("| start | " + " | ".join(f"{len(h)} hidden: held out / fitted" for h in adequacy.HIDDEN_OPTIONS)
          + " | kept |")
    print("|---|" + "---:|" * (len(adequacy.HIDDEN_OPTIONS) + 1))
    for seed in [None, *args.jitter_seeds]:
        k, rows = hidden_table(recording, seed, args.evaluations)
        cells = [f"{r['heldout_error']:.3g} / {r['fitted_error']:.5g}" for r in rows]
        print(f"| {'declared' if seed is None else f'jitter {seed}'} | " + " | ".join(cells) + f" | {k} |",
              flush=True)


if __name__ == "__main__":
    main()
