"""``thermodrift compensate DIR --input TABLE --manifest M.yaml --out VALUES.csv``: stream a recording through a
compensator package one row at a time, as a controller calls it, and write the values a CNC accepts.

Rows are read with the manifest's column names and units (converted to the units the model was trained in);
``--input -`` reads CSV rows from stdin as they arrive. An empty or non-numeric cell is a fault of that row
(held or fallback, named in the audit), never interpolated and never a reason to stop. Whatever cannot be
trusted (a limit that is not a positive finite number, a damaged package, a malformed probe file, a missing output
folder, an input without rows, an unknown format or unit) stops before the first row: one line, exit code 2,
nothing written. This module only parses options; the checks and the per-row loop are
:mod:`thermodrift.compensator.stream`'s.
"""

from __future__ import annotations

import argparse
import difflib
import sys

from thermodrift.core.cli import options
from thermodrift.core.errors import InputError



def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("package", metavar="DIR", help="a folder written by `thermodrift export`")
    parser.add_argument("--input", required=True, help="table of input rows (.csv, .parquet, .xlsx), or - for CSV "
                                                       "rows on stdin")
    parser.add_argument("--manifest", required=True, help="YAML manifest naming the table's columns and units")
    options.add_out(parser, "values to write (CSV), or - for stdout")
    from thermodrift.core import registry  # the saved listing: --help stays fast

    parser.add_argument("--cnc", default="csv", metavar="FORMAT",
                        help="controller format, a registered cnc component (`thermodrift plugins`): "
                             f"{', '.join(registry.listing().names('cnc'))}; csv (default): time_s, <target>_um, "
                             "<target>_raw_um, <target>_status")
    parser.add_argument("--audit", default=None, help="JSON lines: every written value with inputs, raw "
                                                      "prediction, limits and reasons")
    parser.add_argument("--max-step-um", type=float, default=None,
                        help="rate limit: |change| per update (µm); default: the package's, from training data")
    parser.add_argument("--clamp-um", type=float, default=None,
                        help="plausibility clamp |value| <= X (µm); default: the package's, from training data")
    parser.add_argument("--no-limits", action="store_true",
                        help="write the model's prediction as is; statuses still say what would have applied")
    parser.add_argument("--probe", default=None, help="CSV of probe measurements: time_s, target, um")
    parser.add_argument("--reference-mm", type=float, default=0.0,
                        help="reference position P0 of the axis line (mm; siemens, beckhoff)")
    parser.add_argument("--detection-unit-um", type=float, default=1.0, help="fanuc detection unit (µm)")
    parser.add_argument("--max-axis-velo-mm-min", type=float, default=10000.0,
                        help="siemens MD32000 MAX_AX_VELO (mm/min)")
    parser.add_argument("--velo-factor", type=float, default=0.01,
                        help="siemens MD32760 COMP_ADD_VELO_FACTOR")
    parser.add_argument("--ipo-cycle-ms", type=float, default=4.0, help="siemens interpolation cycle (ms)")


def run(args: argparse.Namespace) -> int:
    from thermodrift import compensator
    from thermodrift.compensator import cnc, stream
    from thermodrift.compensator.audit import Audit
    from thermodrift.core import registry

    # Everything is checked before the first row, so a refusal writes nothing (one line, exit code 2).
    stream.check_settings({"--max-step-um": (args.max_step_um, "µm"), "--clamp-um": (args.clamp_um, "µm"),
                           "--detection-unit-um": (args.detection_unit_um, "µm"),
                           "--max-axis-velo-mm-min": (args.max_axis_velo_mm_min, "mm/min"),
                           "--velo-factor": (args.velo_factor, "a fraction"),
                           "--ipo-cycle-ms": (args.ipo_cycle_ms, "ms"),
                           "--reference-mm": (args.reference_mm, "mm")}, finite=("--reference-mm",))
    _check_format(args.cnc, registry.listing().names("cnc"))  # the saved listing: no plugin imported for it
    stream.check_writable(args.out, "output")
    stream.check_writable(args.audit, "audit log")
    pkg = compensator.load(args.package)
    time_col, time_scale, convert, run_col, roles = _manifest(args.manifest, pkg.inputs)
    probes = stream.read_probes(args.probe, pkg.targets) if args.probe else None
    header, rows = stream.open_rows(args.input)
    parse = _Watched(stream.Rows(header, time_col, time_scale, pkg.inputs, convert, args.input, run_col), pkg, roles)
    comp = pkg.compensator(max_step_um=args.max_step_um, clamp_um=args.clamp_um, limits=not args.no_limits,
                           probes=probes)
    # the format through the compensator's reader of the same door: the training plugins stay unimported
    writer = cnc.writer(pkg, args.cnc, reference_mm=args.reference_mm, detection_unit_um=args.detection_unit_um,
                        max_axis_velo_mm_min=args.max_axis_velo_mm_min, velo_factor=args.velo_factor,
                        ipo_cycle_s=args.ipo_cycle_ms / 1000.0)
    out = sys.stdout if args.out == "-" else open(args.out, "w", newline="", encoding="utf-8")
    audit_fh = open(args.audit, "w", encoding="utf-8") if args.audit else None
    try:
        n = stream.run(comp, writer, rows, parse, out, Audit(audit_fh, pkg, comp) if audit_fh else None,
                       flush=args.out == "-" or args.input == "-")
    finally:
        if out is not sys.stdout:
            out.close()
        if audit_fh:
            audit_fh.close()
    if args.out != "-":
        print(f"wrote {args.cnc} values for {n} input rows to {args.out}"
              + (f", audit in {args.audit}" if args.audit else ""))
    beyond = parse.watch.found()
    if beyond:
        from thermodrift.core.automl import extrapolation

        print(f"thermodrift: warning: {extrapolation.summary(beyond, f'the input ({n} rows)')}", file=sys.stderr)
    return 0


class _Watched:
    """The row parser, watching each input against its training range (:class:`extrapolation.Watch`): the first
    row on which an input leaves it by more than the margin is said at once on stderr (the model extrapolates)."""

    def __init__(self, rows, pkg, roles: dict[str, tuple[str, str]]):
        from thermodrift.core.automl import extrapolation

        self.rows, self.n = rows, 0
        self.watch = extrapolation.Watch(pkg.limits["inputs"], pkg.inputs, {c: r for c, (r, _) in roles.items()},
                                         {c: u for c, (_, u) in roles.items()})

    def run(self, cells):
        return self.rows.run(cells)

    def parse(self, cells):
        t, values = self.rows.parse(cells)
        self.n += 1
        for name in self.watch.update(values):
            print(f"thermodrift: warning: input row {self.n}: {name} = {values[self.watch.names.index(name)]:.4g} "
                  "is beyond its training range by more than the margin: the model extrapolates", file=sys.stderr)
        return t, values


def _check_format(name: str, known) -> None:
    """One line with "did you mean" for an unknown ``--cnc`` format, as every other verb answers a misspelt name."""
    if name not in known:
        close = difflib.get_close_matches(name, list(known), n=1)
        raise InputError(f"unknown CNC format {name!r}", hint=(f"did you mean {close[0]!r}? " if close else "")
                         + f"choose from {', '.join(sorted(known))}")


def _manifest(path: str, inputs: list[str]):
    """(time column, time scale to s, {input column: (scale, offset)} to the canonical units the model was
    trained in, the run column or None), read with core/recording's manifest reader and unit table (one home for units)."""
    from thermodrift.core import recording  # its manifest reader and unit table

    manifest = recording.read_manifest(path, ())
    missing = [c for c in inputs if c not in manifest.channels]
    if missing:
        raise InputError("the manifest does not name an input of the package", file=path, column=missing[0],
                         hint=f"name every input the model reads: {', '.join(inputs)}")
    convert, roles = {}, {}
    for c in inputs:
        role, unit, _ = manifest.channels[c]
        if role in ("condition", "ignore"):
            raise InputError(f"the package reads this column as a number, the manifest gives role {role}", file=path,
                             column=c, hint="give it the role and unit it had in training")
        convert[c] = recording.UNITS[role][1][unit]
        roles[c] = (role, recording.UNITS[role][0] if unit != recording.UNITLESS else unit)
    scale = None if manifest.time_unit is None else recording.TIME_UNITS[manifest.time_unit]
    # scale None: seconds or timestamps; roles: {input: (role, unit)}
    return manifest.time, scale, convert, manifest.run, roles
