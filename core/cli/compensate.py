"""``thermodrift compensate DIR --input TABLE --manifest M.yaml --out VALUES.csv``: stream a recording through a
compensator package one row at a time, as a controller calls it, and write the values a CNC accepts.

Rows are read with the manifest's column names and units (converted to the units the model was trained in);
``--input -`` reads CSV rows from stdin as they arrive. An empty or non-numeric cell is a fault of that row
(held or fallback, named in the audit), never interpolated and never a reason to stop. A missing column, an
unknown unit or a package that does not load stops before the first row: one line, exit code 2.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from thermodrift.core.cli import options

FORMAT_HELP = "csv (default): time_s, <target>_um, <target>_raw_um, <target>_status; siemens, fanuc, beckhoff"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("package", metavar="DIR", help="a folder written by `thermodrift export`")
    parser.add_argument("--input", required=True, help="table of input rows (.csv, .parquet, .xlsx), or - for CSV "
                                                       "rows on stdin")
    parser.add_argument("--manifest", required=True, help="YAML manifest naming the table's columns and units")
    options.add_out(parser, "values to write (CSV), or - for stdout")
    parser.add_argument("--cnc", default="csv", choices=("csv", "siemens", "fanuc", "beckhoff"), help=FORMAT_HELP)
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
    import numpy as np

    from thermodrift import compensator
    from thermodrift.compensator import cnc
    from thermodrift.compensator.audit import Audit
    from thermodrift.core.errors import InputError

    try:
        pkg = compensator.load(args.package)
    except (compensator.PackageError, ValueError) as exc:
        raise InputError(f"not a usable compensator package ({exc})", file=args.package,
                         hint="pass the folder that `thermodrift export` wrote") from None
    time_col, time_scale, convert = _manifest(args.manifest, pkg.inputs)
    probes = _probes(args.probe, pkg.targets) if args.probe else None
    comp = pkg.compensator(max_step_um=args.max_step_um, clamp_um=args.clamp_um, limits=not args.no_limits,
                           probes=probes)
    writer = cnc.Writer(pkg, args.cnc, reference_mm=args.reference_mm, detection_unit_um=args.detection_unit_um,
                        max_axis_velo_mm_min=args.max_axis_velo_mm_min, velo_factor=args.velo_factor,
                        ipo_cycle_s=args.ipo_cycle_ms / 1000.0)
    source = args.input
    header, rows = _rows(source)
    where = {name.strip(): i for i, name in enumerate(header)}
    for column in [time_col, *convert]:
        if column not in where:
            raise InputError("column not found in the input header", file=source, column=column,
                             hint=f"the package reads {', '.join(pkg.inputs)} and the time column {time_col!r}")
    t_idx = where[time_col]
    idx = [where[c] for c in pkg.inputs]
    scale = np.array([convert[c][0] for c in pkg.inputs])
    offset = np.array([convert[c][1] for c in pkg.inputs])
    out = sys.stdout if args.out == "-" else open(args.out, "w", newline="", encoding="utf-8")
    audit_fh = open(args.audit, "w", encoding="utf-8") if args.audit else None
    try:
        table = csv.writer(out)
        table.writerow(writer.header())
        audit = Audit(audit_fh, pkg, comp) if audit_fh else None
        for cells in rows:
            t = _number(cells[t_idx] if t_idx < len(cells) else "") * time_scale
            values = np.array([_number(cells[i]) if i < len(cells) else np.nan for i in idx]) * scale + offset
            step = comp.hold_row(t, values, [("time", "time_unreadable")]) if not np.isfinite(t) \
                else comp.update(t, values)
            table.writerows(writer.rows(step))
            if audit is not None:
                audit.write(step, values)
            if args.out == "-" or source == "-":
                out.flush()  # a controller reads each value as it is written
    finally:
        if out is not sys.stdout:
            out.close()
        if audit_fh:
            audit_fh.close()
    return 0


def _number(cell) -> float:
    """A cell as a float; empty or non-numeric -> NaN (a fault of that row, handled downstream)."""
    try:
        return float(cell)
    except (TypeError, ValueError):
        return float("nan")


def _rows(source: str):
    """(header, iterator of rows as lists of cells): CSV streamed line by line (stdin for ``-``); Parquet and
    XLSX read whole."""
    from thermodrift.core.errors import InputError

    if source == "-":
        reader = csv.reader(sys.stdin)
    else:
        path = Path(source)
        if not path.is_file():
            raise InputError("input table not found", file=source, hint="check the path, or pass - for stdin")
        if path.suffix.lower() in (".parquet", ".xlsx"):
            import pandas as pd

            frame = pd.read_parquet(path) if path.suffix.lower() == ".parquet" else pd.read_excel(path)
            return [str(c) for c in frame.columns], iter(frame.astype(object).to_numpy().tolist())
        reader = csv.reader(open(path, newline="", encoding="utf-8-sig"))
    try:
        header = next(reader)
    except StopIteration:
        raise InputError("the input has no header row", file=source,
                         hint="the first line names the columns, as in the manifest") from None
    return header, reader


def _manifest(path: str, inputs: list[str]):
    """(time column, time scale to s, {input column: (scale, offset)} to the canonical units the model was
    trained in), read with core/recording's manifest reader and unit table (one home for units)."""
    from thermodrift.core.errors import InputError
    from thermodrift.core import recording  # its manifest reader and unit table

    manifest = recording.read_manifest(path, ())
    missing = [c for c in inputs if c not in manifest.channels]
    if missing:
        raise InputError("the manifest does not name an input of the package", file=path, column=missing[0],
                         hint=f"name every input the model reads: {', '.join(inputs)}")
    convert = {}
    for c in inputs:
        role, unit, _ = manifest.channels[c]
        if role in ("condition", "ignore"):
            raise InputError(f"the package reads this column as a number, the manifest gives role {role}", file=path,
                             column=c, hint="give it the role and unit it had in training")
        convert[c] = recording.UNITS[role][1][unit]
    unit = manifest.time_unit or "s"
    return manifest.time, recording.TIME_UNITS[unit], convert


def _probes(path: str, targets: list[str]) -> list[tuple[float, int, float]]:
    """Probe rows (time_s, target, um) as (time s, target index, µm)."""
    import pandas as pd

    from thermodrift.core.errors import InputError

    if not Path(path).is_file():
        raise InputError("probe file not found", file=path, hint="a CSV with columns time_s, target, um")
    frame = pd.read_csv(path)
    for column in ("time_s", "target", "um"):
        if column not in frame.columns:
            raise InputError("column not found", file=path, column=column,
                             hint="a probe file has columns time_s, target, um")
    out = []
    for row, (t, target, um) in enumerate(frame[["time_s", "target", "um"]].itertuples(index=False), start=2):
        if str(target) not in targets:
            raise InputError(f"unknown target {target!r}", file=path, column="target", row=row,
                             hint=f"the package's targets are {', '.join(targets)}")
        out.append((float(t), targets.index(str(target)), float(um)))
    return out
