"""``thermodrift bench NAME [ARGS...]``: run ``benchmarks/bench_NAME.py`` of a source checkout.

Benchmarks are development tools (they need the ``bench`` extra and the recordings in ../shared/data), so they
live in the repository's ``benchmarks/`` folder, not in the installed package; this verb finds that folder from
the current directory upwards (or ``--dir``) and runs the script with the remaining arguments.
"""

from __future__ import annotations

import argparse
import runpy
import sys
from pathlib import Path

from thermodrift.core.errors import InputError


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", nargs="?", help="benchmark name, e.g. samplers or physics (omit to list them)")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="arguments passed to the benchmark script")
    parser.add_argument("--dir", type=Path, default=None, help="the benchmarks/ folder (default: searched upwards)")


def _folder(explicit: Path | None) -> Path:
    if explicit is not None:
        if not explicit.is_dir():
            raise InputError(f"{explicit} is not a folder", hint="pass the repository's benchmarks/ folder")
        return explicit
    for base in (Path.cwd(), *Path.cwd().parents):
        if (base / "benchmarks").is_dir():
            return base / "benchmarks"
    raise InputError("no benchmarks/ folder here or above", hint="run from a thermodrift checkout or pass --dir")


def run(args: argparse.Namespace) -> int:
    folder = _folder(args.dir)
    scripts = {p.stem.removeprefix("bench_"): p for p in sorted(folder.glob("bench_*.py"))}
    if not args.name:
        print("benchmarks:", ", ".join(scripts) or "none")
        return 0
    if args.name not in scripts:
        raise InputError(f"unknown benchmark {args.name!r}", hint=f"choose from {', '.join(scripts)}")
    sys.argv = [str(scripts[args.name]), *args.args]
    try:
        runpy.run_path(str(scripts[args.name]), run_name="__main__")
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 0
    return 0
