"""``thermodrift report <sweep id or parent run id>``: the studies' tables from MLflow (Markdown + CSV)."""

from __future__ import annotations

import argparse

from thermodrift.core.cli import options


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("ref", help="sweep id (the multirun/<id> folder name) or the sweep's parent MLflow run id")
    options.add_tracking_uri(parser)
    options.add_out(parser, "output folder", default="reports/<sweep id>")


def run(args: argparse.Namespace) -> int:
    from thermodrift.core import report, tracking

    tracking.setup(args.tracking_uri, "thermodrift")
    client = tracking.client()
    parent = report.parent_run(client, args.ref)
    sweep = parent.data.tags.get("sweep_id") or parent.info.run_id
    out = args.out.replace("<sweep id>", sweep)
    paths = report.log_to_parent(client, parent.info.run_id, out)
    print(paths["report.md"].read_text(encoding="utf-8"))
    print(f"written: {', '.join(str(p) for p in paths.values())}; logged on run {parent.info.run_id} (report/)")
    return 0
