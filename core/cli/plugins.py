"""``thermodrift plugins [--json]``: every registered component by kind, with its origin and what it is."""

from __future__ import annotations

import argparse
import inspect
import json
import re
import sys

from thermodrift.core import registry
from thermodrift.core.cli import plain


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")


def describe(component: registry.Component) -> str:
    """One sentence of plain text: the factory's ``description`` attribute, else the first sentence of its own
    docstring (not one inherited from a base class), else of its module's docstring; '' without any."""
    factory = component.factory
    own = factory.__dict__.get("__doc__") if isinstance(factory, type) else getattr(factory, "__doc__", None)
    for text in (getattr(factory, "description", None), own,
                 getattr(sys.modules.get(getattr(factory, "__module__", "")), "__doc__", None)):
        if isinstance(text, str) and text.strip():
            paragraph = " ".join(inspect.cleandoc(text).split("\n\n")[0].split())
            return plain(re.split(r"(?<=\.)\s+(?=[A-Z`])", paragraph)[0]).strip()
    return ""


def run(args: argparse.Namespace) -> int:
    reg = registry.default()
    listing = {
        kind: [{"name": c.name, "origin": c.origin, "module": c.module, "description": describe(c)}
               for c in (reg.get(kind, n) for n in reg.names(kind))]
        for kind in registry.KINDS
    }
    if args.json:
        print(json.dumps({"components": listing, "searchpaths": reg.searchpaths, "failures": reg.failures},
                         indent=2, ensure_ascii=False))
        return 0
    rows = [(kind, item["name"], item["origin"], item["description"]) for kind, items in listing.items()
            for item in items]
    header = ("KIND", "NAME", "ORIGIN", "DESCRIPTION")
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(3)]
    previous = header[0]
    for row in [header, *rows]:
        if row[0] != previous and previous != header[0]:
            print()
        print("  ".join(f"{cell:<{w}}" for cell, w in zip(row[:3], widths)) + "  " + row[3])
        previous = row[0]
    for origin, error in reg.failures.items():
        print(f"failed to load {origin}: {error}")
    return 0
