"""``thermodrift validate TABLE --manifest M.yaml``: load a recording and print its summary."""

from __future__ import annotations

import argparse


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("table", help="recording table (.csv, .parquet or .xlsx)")
    parser.add_argument("--manifest", required=True, help="YAML manifest giving each channel a role and unit")


def run(args: argparse.Namespace) -> int:
    from thermodrift.core.recording import load_recording

    print(load_recording(args.table, args.manifest).summary())
    return 0
