"""``thermodrift diagnose``: find the physics a thermal model leaves out of a recording.

Examples::

    thermodrift diagnose ../shared/data/fl_thermal/data.xlsx --manifest plugins/datasets/fl_thermal.yaml --out runs/dx
    thermodrift diagnose sim.csv --manifest sim.manifest.yaml --network baseline.yaml --tracking-uri file:./mlruns

Calibrates the baseline (``auto``: built from the manifest; a spec: its parameters kept, offsets and
sensitivities solved), screens every registered mechanism at every place, fits the best by re-simulation and
selects forward; writes ``report.json``, ``report.md``, ``residuals.csv``, ``residual_map.png`` and
``fit.png`` into ``--out`` (see :mod:`thermodrift.core.physics.diagnose.report`).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from thermodrift.core.cli import options
from thermodrift.core.errors import InputError


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("table", help="recording table (CSV, Parquet or XLSX)")
    parser.add_argument("--manifest", required=True, help="manifest YAML of the table")
    parser.add_argument("--network", default="auto",
                        help="'auto' (baseline from the manifest, default), a spec YAML or a name in conf/network")
    options.add_out(parser, "output folder", default="diagnosis")
    options.add_tracking_uri(parser, optional=True)
    parser.add_argument("--seed", type=int, default=0, help="seed of the block bootstrap (default 0)")
    parser.add_argument("--alpha", type=float, default=0.01,
                        help="family-wise level of the likelihood-ratio tests, Bonferroni-corrected (default 0.01)")
    parser.add_argument("--max-rounds", type=int, default=3, help="forward-selection rounds at most (default 3)")
    parser.add_argument("--mechanisms", nargs="+", default=None, metavar="ID",
                        help="screen only these mechanisms (default: every registered one)")


def run(args: argparse.Namespace) -> int:
    from thermodrift.core.physics.diagnose import diagnose, report
    from thermodrift.core.physics.spec import load_network
    from thermodrift.core.recording import load_recording

    if not 0 < args.alpha < 1:
        raise InputError(f"--alpha must be in (0, 1), got {args.alpha}")
    if args.max_rounds < 1:
        raise InputError("--max-rounds must be ≥ 1")
    recording = load_recording(args.table, args.manifest, require=())
    network = None if args.network == "auto" else load_network(args.network)
    d = diagnose(recording, network, seed=args.seed, alpha=args.alpha, max_rounds=args.max_rounds,
                 only=args.mechanisms)
    out = Path(args.out)
    command = "thermodrift " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv else ""
    doc = report.write(d, out, command)
    if args.tracking_uri:
        from thermodrift.core import tracking

        tracking.log_diagnosis(d, doc, out, args.tracking_uri, f"diagnose {Path(args.table).name}", args.seed)
    print(doc["verdict"])
    for f in doc["findings"]:
        print(f"  found {f['mechanism']} (confidence {f['confidence']:.2f}): {f['parameters']}")
    print(f"wrote {out}")
    return 0
