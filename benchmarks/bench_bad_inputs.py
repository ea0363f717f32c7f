"""Time and peak memory of `thermodrift validate` on every malformed input: ``thermodrift bench bad_inputs``.

Each case (tests/data/bad plus the large cases written into a temporary folder: a 115 MB line, 2 GB of NUL
bytes) runs in its own process; its peak resident memory comes from ``os.wait4``. Targets per case: exit code 2,
one line on stderr, no traceback, under 10 s and 1 GB. Prints one row per case and exits 1 if any misses.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
sys.path.insert(0, str(DATA))
import make_corpus  # noqa: E402

MAX_S, MAX_MB = 10.0, 1024.0


def measure(table: Path, manifest: Path) -> tuple[int, str, float, float]:
    """Exit code, stderr, wall seconds and peak RSS (MB) of one `thermodrift validate` process."""
    exe = Path(sys.executable).with_name("thermodrift")
    start = time.perf_counter()
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen([str(exe), "validate", str(table), "--manifest", str(manifest)],
                                stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        seconds = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        text = err.read().decode("utf-8", "replace")
    return proc.returncode, text, seconds, usage.ru_maxrss / 1024.0  # Linux reports KB


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", help="case names to run (default: all)")
    args = parser.parse_args()
    cases = {}
    for folder in sorted(p for p in (DATA / "bad").iterdir() if p.is_dir()):
        spec = yaml.safe_load((folder / "expect.yaml").read_text(encoding="utf-8"))
        cases[folder.name] = (folder / spec["table"], folder / spec["manifest"])
    with tempfile.TemporaryDirectory() as tmp:
        for name, (table, manifest, _) in make_corpus.write_large_cases(Path(tmp)).items():
            cases[name] = (table, manifest)
        if args.only:
            cases = {k: v for k, v in cases.items() if k in args.only}
        print(f"{'case':34s} {'exit':>4s} {'lines':>5s} {'s':>6s} {'peak MB':>8s}  ok")
        misses = 0
        for name, (table, manifest) in cases.items():
            code, err, seconds, peak = measure(table, manifest)
            lines = len(err.strip().splitlines())
            ok = code == 2 and lines == 1 and "Traceback" not in err and seconds < MAX_S and peak < MAX_MB
            misses += not ok
            print(f"{name:34s} {code:4d} {lines:5d} {seconds:6.2f} {peak:8.0f}  {'yes' if ok else 'NO'}")
    print(f"{len(cases)} cases, {misses} missing a target (exit 2, one line, no traceback, < {MAX_S:g} s, "
          f"< {MAX_MB:g} MB)")
    return 1 if misses else 0


if __name__ == "__main__":
    sys.exit(main())
