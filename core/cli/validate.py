"""``thermodrift validate TABLE [TABLE ...] --manifest M.yaml``: load a recording and print its summary (several
tables, like the sheets of ``sheet: all`` or the blocks of a ``run:`` column, are independent runs, listed)."""

from __future__ import annotations

import argparse


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("table", nargs="+", help="recording table(s) (.csv, .parquet or .xlsx); several tables or "
                        "a quoted glob pattern are independent runs of one machine")
    parser.add_argument("--manifest", required=True, help="YAML manifest giving each channel a role and unit")


def run(args: argparse.Namespace) -> int:
    from thermodrift.core.recording import load_recording

    tables = args.table if len(args.table) > 1 else args.table[0]
    print(load_recording(tables, args.manifest).summary())
    return 0
