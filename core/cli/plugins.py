"""``thermodrift plugins [--json]``: every registered component by kind, with its origin distribution."""

from __future__ import annotations

import argparse
import json

from thermodrift.core import registry


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")


def run(args: argparse.Namespace) -> int:
    reg = registry.default()
    listing = {
        kind: [{"name": c.name, "origin": c.origin, "module": c.module} for c in
               (reg.get(kind, n) for n in reg.names(kind))]
        for kind in registry.KINDS
    }
    if args.json:
        print(json.dumps({"components": listing, "searchpaths": reg.searchpaths, "failures": reg.failures},
                         indent=2, ensure_ascii=False))
        return 0
    for kind, items in listing.items():
        print(f"{kind}s ({len(items)}):")
        for item in items:
            print(f"  {item['name']:<28} {item['origin']:<28} {item['module']}")
    for origin, error in reg.failures.items():
        print(f"failed to load {origin}: {error}")
    return 0
