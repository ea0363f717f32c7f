"""``thermodrift diagnose``: find the physics a thermal model leaves out of a recording.

Examples::

    thermodrift diagnose ../shared/data/fl_thermal/data.xlsx --manifest plugins/datasets/fl_thermal.yaml --out runs/dx
    thermodrift diagnose sim.csv --manifest sim.manifest.yaml --network baseline.yaml --tracking-uri file:./mlruns
    thermodrift diagnose data.csv --manifest data.yaml --simulation my_fe_model.csv --out runs/dx

Calibrates the baseline (``auto``: built from the manifest; a spec: its parameters kept, offsets and
sensitivities solved), screens every registered mechanism at every place, fits the best by re-simulation and
selects forward; writes ``report.json``, ``report.md``, ``residuals.csv``, ``residual_map.png`` and
``fit.png`` into ``--out`` (see :mod:`thermodrift.core.physics.diagnose.report`).

With ``--simulation SIM`` (a table from any simulator: the manifest's time column and any of the recording's
temperature and displacement channels, same names and units; ``thermodrift simulate --network spec.yaml --drive
TABLE --manifest M.yaml --out SIM.csv`` writes one) what is missing is found against that simulation instead
(:mod:`thermodrift.core.physics.diagnose.against_simulation`); ``baseline`` is then the calibrated simulation.
"""

from __future__ import annotations

import argparse
import os
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
    parser.add_argument("--alpha", type=float, default=None,
                        help="false-discovery level of the likelihood-ratio tests: Benjamini-Hochberg over each round's "
                             "candidates, spent as alpha/2, alpha/4, ... over the rounds (default 0.01); with a "
                             "stochastic network (building_ti), the level of each forward step's LR test (default 0.05)")
    parser.add_argument("--max-rounds", type=int, default=3, help="forward-selection rounds at most (default 3)")
    parser.add_argument("--simulation", default=None, metavar="SIM",
                        help="the user's simulation of this recording (CSV, Parquet or XLSX): find what it leaves out")
    parser.add_argument("--simulation-inputs", nargs="+", default=None, metavar="ROLE",
                        choices=("ambient", "coolant_inlet", "cutting_power", "axis_velocity", "none"),
                        help="with --simulation: the recorded inputs that drove it besides the speed ('none': only "
                             "the speed; default: read from its traces)")
    parser.add_argument("--mechanisms", nargs="+", default=None, metavar="ID",
                        help="screen only these mechanisms (default: every registered one)")
    parser.add_argument("--stochastic", action="store_true",
                        help="stochastic grey-box identification (process noise, Kalman likelihood); implied by a "
                             "stochastic network such as building_ti, whose structure is then forward-selected")
    parser.add_argument("--targets", nargs="+", default=None, metavar="CHANNEL",
                        help="with a stochastic network: the measured temperature (default: the only one)")


def run(args: argparse.Namespace) -> int:
    from thermodrift.core.physics.stochastic.rc import is_stochastic_spec

    if args.network != "auto" and is_stochastic_spec(args.network):
        return _select_structure(args)
    if args.stochastic:
        return _stochastic_machine(args)
    if args.alpha is None:
        args.alpha = 0.01
    from thermodrift.core.physics.diagnose import diagnose, report
    from thermodrift.core.physics.spec import load_network
    from thermodrift.core.recording import load_recording

    if not 0 < args.alpha < 1:
        raise InputError(f"--alpha must be in (0, 1), got {args.alpha}")
    if args.max_rounds < 1:
        raise InputError("--max-rounds must be ≥ 1")
    recording = load_recording(args.table, args.manifest, require=())
    if args.simulation:
        from thermodrift.core.physics.diagnose import against_simulation, simulation_table

        if args.network != "auto":
            raise InputError("give --simulation or --network, not both")
        sim = simulation_table.read_simulation(args.simulation, recording, args.manifest)
        given = None if args.simulation_inputs is None else [r for r in args.simulation_inputs if r != "none"]
        d = against_simulation.diagnose_simulation(recording, sim, simulated_inputs=given, seed=args.seed,
                                                   only=args.mechanisms)
    else:
        network = None if args.network == "auto" else load_network(args.network)
        d = diagnose(recording, network, seed=args.seed, alpha=args.alpha, max_rounds=args.max_rounds,
                     only=args.mechanisms)
        from thermodrift.core import registry
        from thermodrift.core.physics.diagnose import status

        d.adequacy["mechanisms"] = status.listing(d, args.mechanisms or registry.default().names("mechanism"))
    out = Path(args.out)
    command = "thermodrift " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv else ""
    doc = report.write(d, out, command)
    if args.tracking_uri:
        from thermodrift.core import tracking

        tracking.log_diagnosis(d, doc, out, args.tracking_uri, f"diagnose {Path(args.table).name}", args.seed)
    print(doc["verdict"])
    untested = [m for m in doc["adequacy"].get("mechanisms", []) if m["status"] != "tested"]
    if untested:
        print("  not tested: " + "; ".join(f"{m['mechanism']} ({m['status']})" for m in untested))
    for f in doc["findings"]:
        print(finding_line(f))
    print(f"wrote {', '.join(str(p) for p in sorted(out.iterdir()) if p.is_file())}")
    return 0


def finding_line(finding: dict) -> str:
    """A finding for the console: its fitted and fixed values (its label when it has neither)."""
    values = {**finding.get("parameters", {}), **finding.get("fixed", {})}
    shown = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in values.items())
    return (f"  found {finding['mechanism']} (confidence {finding['confidence']:.2f}): "
            f"{shown or finding.get('label') or 'no parameter to estimate'}")


def _select_structure(args: argparse.Namespace) -> int:
    """Forward selection of a stochastic network's structure (a building from ``building_ti``)."""
    from thermodrift.core.physics.stochastic import diagnosis, load
    from thermodrift.core.recording import load_recording

    if args.simulation:
        raise InputError("--simulation takes the machine finder; a stochastic network selects its own structure")
    alpha = 0.05 if args.alpha is None else args.alpha
    if not 0 < alpha < 1:
        raise InputError(f"--alpha must be in (0, 1), got {alpha}")
    recording = load_recording(args.table, args.manifest, require=("temperature",))
    net = load(args.network)
    target = args.targets[0] if args.targets else None
    workers = min(2, os.cpu_count() or 1)  # a round's candidates in parallel; the result does not depend on it
    sel, data, target = diagnosis.select(recording, net, seed=args.seed, alpha=alpha, target=target,
                                         progress=lambda line: print(line, flush=True), workers=workers,
                                         only=args.mechanisms)
    out = Path(args.out)
    command = "thermodrift " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv else ""
    doc = diagnosis.report(sel, data, recording, net, target, out, command)
    h = doc["htc"]
    ci = f" [{h['ci95'][0]:.4g}, {h['ci95'][1]:.4g}]" if h["ci95"] else ""
    print(f"selected {doc['selected']} ({' -> '.join(s['name'] for s in doc['selection_path'] if s['accepted'])}); "
          f"HTC {h['value']:.4g}{ci} {h['unit']}; one-step residuals "
          f"{'white' if doc['one_step']['whiteness']['white'] else 'not white'}; {doc['seconds']:.0f} s")
    print(f"wrote {out}")
    return 0


def _stochastic_machine(args: argparse.Namespace) -> int:
    """Mechanisms by likelihood ratio on the innovations of a stochastic ``auto`` baseline."""
    import json

    from thermodrift.core.physics.stochastic import machine
    from thermodrift.core.recording import load_recording

    if args.simulation or args.network != "auto":
        raise InputError("--stochastic on a machine starts from the auto baseline: leave out --simulation and "
                         "--network")
    alpha = 0.01 if args.alpha is None else args.alpha
    if not 0 < alpha < 1:
        raise InputError(f"--alpha must be in (0, 1), got {alpha}")
    recording = load_recording(args.table, args.manifest, require=())
    doc = machine.select_mechanisms(recording, seed=args.seed, alpha=alpha, max_rounds=args.max_rounds,
                                    only=args.mechanisms, progress=lambda line: print(line, flush=True))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    doc["command"] = "thermodrift " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv else ""
    (out / "report.json").write_text(json.dumps(doc, indent=1, ensure_ascii=False, default=float) + "\n",
                                     encoding="utf-8")
    print(doc["verdict"])
    print(f"wrote {out}")
    return 0
