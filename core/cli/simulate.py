"""``thermodrift simulate``: write a simulated recording (table + manifest) and its ground truth.

Examples::

    thermodrift simulate --machine vmc_spindle_s2 --seed 3 --out runs/sim
    thermodrift simulate --machine motorized_spindle_s3 --scenario fl_thermal --dt 60 --format parquet
    thermodrift simulate --network my_machine.yaml --scenario iso230_3_speed_spectrum \\
        --mechanism slow_structural_mode:tau_h=6,gain_um_K=-2 --mechanism sensor_lag
    thermodrift simulate --network my_machine.yaml --drive data.csv --manifest data.yaml --out sim.csv

Writes ``<name>.<format>``, ``<name>.manifest.yaml`` (load both with ``thermodrift validate``) and
``<name>.truth.json``: the network after mechanisms, the mechanisms with their parameters, the drawn sensor
offsets, the scenario and the seed.

With ``--drive TABLE --manifest M.yaml`` the recorded inputs (speed, ambient, coolant inlet, cutting power, axis
velocity) drive the network instead of a scenario, and ``--out`` is the simulation table to write (CSV, Parquet
or XLSX by suffix): the manifest's time column and what every sensor of the network reads, without noise, on
the recording's times; ``thermodrift diagnose TABLE --manifest M.yaml --simulation SIM`` reads it.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from thermodrift.core.cli import options
from thermodrift.core.errors import InputError


def configure(parser: argparse.ArgumentParser) -> None:
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--machine", default=None,
                        help="simulated dataset from the registry (default demo_spindle; see `thermodrift plugins`)")
    source.add_argument("--network", default=None, help="network spec: a YAML path or a name in conf/network")
    parser.add_argument("--scenario", default=None,
                        help="named scenario (demo, fl_thermal, iso230_3_speed_spectrum, s1_conditions, ...); "
                             "default: the machine's own")
    parser.add_argument("--seed", type=int, default=0, help="seed of sensor offsets and noise (default 0)")
    parser.add_argument("--hours", type=float, default=None, help="keep only the first HOURS of the scenario")
    parser.add_argument("--dt", type=float, default=None, help="sampling interval in s (default: the scenario's)")
    parser.add_argument("--mechanism", action="append", default=[], metavar="ID[:P=V,...]",
                        help="apply a mechanism on top (repeatable), e.g. sensor_lag:lag_s=300")
    options.add_out(parser, "output folder", default=".")
    parser.add_argument("--format", choices=("csv", "parquet", "xlsx"), default="csv", help="table format")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--drive", default=None, metavar="TABLE",
                        help="with --network and --manifest: drive the network with this recording's inputs and "
                             "write the simulation table to --out (a .csv, .parquet or .xlsx path)")
    parser.add_argument("--manifest", default=None, help="manifest YAML of the --drive table")


def run(args: argparse.Namespace) -> int:
    if args.drive or args.manifest:
        return _run_driven(args)
    from tqdm import tqdm

    from thermodrift.core import registry
    from thermodrift.core.physics import scenarios
    from thermodrift.core.physics.spec import apply_mechanism_list, load_network
    from thermodrift.core.physics.synthetic import synthesize

    # The bar is closed (cleared) on any exit, so an error prints on a line of its own.
    with tqdm(total=4, desc="simulate", unit="step", disable=args.no_progress, leave=False) as steps:
        extra = [_parse_mechanism(text) for text in args.mechanism]
        if args.network:
            network = load_network(args.network)
            name = network.name
            scen = scenarios.build(args.scenario or "iso230_3_speed_spectrum",
                                   **({"dt_s": args.dt} if args.dt else {}))
        else:
            name = args.machine or "demo_spindle"
            machine = registry.get("dataset", name).factory
            if not hasattr(machine, "generate"):
                raise InputError(f"dataset {name!r} is not a simulated machine",
                                 hint="use one of demo_spindle, turning_centre_s1, vmc_spindle_s2, "
                                      "motorized_spindle_s3")
            network = load_network(machine.name)
            scen_name = args.scenario or machine.scenario
            dt = args.dt or (machine.dt_s if scen_name == machine.scenario else None)
            scen = scenarios.build(scen_name, **({"dt_s": dt} if dt else {}))
        if args.hours is not None:
            if args.hours <= 0:
                raise InputError("--hours must be positive")
            scen = scen.head(args.hours)
        steps.update()
        network = apply_mechanism_list(network, extra)
        steps.set_description("simulate: integrating")
        synthetic = synthesize(network, scen, args.seed, source=f"{name}[seed={args.seed},{scen.name}]")
        synthetic.truth["machine"] = name
        steps.update(2)
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        stem = f"{name}_seed{args.seed}"
        table, manifest = out / f"{stem}.{args.format}", out / f"{stem}.manifest.yaml"
        truth = out / f"{stem}.truth.json"
        steps.set_description("simulate: writing")
        synthetic.recording.write(table, manifest)
        truth.write_text(json.dumps(synthetic.truth, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
        steps.update()
    rec = synthetic.recording
    print(f"{rec.duration_s / 3600:.1f} h, {len(rec)} samples of {rec.sampling_interval_s:g} s, "
          f"{len(rec.temperatures.columns)} temperatures, {len(rec.displacements.columns)} displacements, "
          f"{rec.conditions().nunique()} working conditions")
    for path in (table, manifest, truth):
        print(path)
    return 0


def _run_driven(args: argparse.Namespace) -> int:
    """``--drive TABLE --manifest M.yaml --network spec --out SIM``: the recorded inputs drive the network."""
    from thermodrift.core.physics.diagnose import simulation_table
    from thermodrift.core.physics.spec import apply_mechanism_list, load_network
    from thermodrift.core.recording import load_recording
    from thermodrift.core.recording.loading import read_manifest

    if not (args.drive and args.manifest and args.network):
        raise InputError("--drive needs --manifest and --network",
                         hint="thermodrift simulate --network spec.yaml --drive TABLE --manifest M.yaml --out SIM.csv")
    if Path(args.out).suffix.lower() not in (".csv", ".parquet", ".xlsx"):
        raise InputError(f"--out {args.out!r} must be a table path with --drive", hint="e.g. --out sim.csv")
    recording = load_recording(args.drive, args.manifest, require=())
    network = apply_mechanism_list(load_network(args.network), [_parse_mechanism(t) for t in args.mechanism])
    frame = simulation_table.drive(network, recording)
    man = read_manifest(args.manifest, ())
    path = simulation_table.write(frame, args.out, man.time, man.time_unit)
    print(f"{len(frame)} samples, {frame.shape[1]} sensors of {network.name} driven by {Path(args.drive).name}")
    print(path)
    return 0


def _parse_mechanism(text: str) -> dict:
    """``"id"`` or ``"id:p=1.5,q=2"`` -> ``{"id": ..., "params": {...}}``."""
    ident, _, rest = text.partition(":")
    params = {}
    for item in filter(None, rest.split(",")):
        key, sep, value = item.partition("=")
        try:
            params[key.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep:
            raise InputError(f"bad --mechanism {text!r}", hint="write ID or ID:PARAM=NUMBER,PARAM=NUMBER")
    return {"id": ident.strip(), "params": params}
