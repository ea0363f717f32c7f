"""The testability probe (benchmarks/probe_testable.py): the screen's own decision for one planted mechanism
against the ``auto`` baseline of an independent recording, before any fit."""

import sys
import tempfile
from pathlib import Path

import pytest

from thermodrift.core.recording import load_recording

from support import load_file

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
PROBE = load_file(BENCH / "probe_testable.py")
sys.path.insert(0, str(BENCH))
import independent  # noqa: E402


def _recording(seed, hidden):
    gen = independent.make_case(seed, hidden, hours=8.0, generator="fd")
    with tempfile.TemporaryDirectory() as folder:
        return load_recording(*gen.write(Path(folder)))


@pytest.mark.parametrize("seed, hidden, kind", [(0, "ambient_coupling", "nested"),
                                                (7, "centrifugal_growth", "testable"),
                                                (10, "thermal_tilt", "skipped")])
def test_the_probe_reports_the_screens_decision(seed, hidden, kind):
    got, why = PROBE.verdict(_recording(seed, hidden), hidden)
    assert got == kind
    if kind == "nested":
        assert why.startswith("nested in the baseline") and "ambient" in why
    if kind == "skipped":
        assert "structure or table node" in why


def test_the_probe_prints_the_ceiling(capsys):
    shown = ["ambient_coupling", "centrifugal_growth"]
    assert PROBE.main(["--generator", "fd", "--per-mechanism", "1", "--only", *shown]) == 0
    out = capsys.readouterr().out
    rows = [[c.strip() for c in r.strip("|").split("|")] for r in out.splitlines() if r.startswith("| fd |")]
    per, total = rows[:-1], rows[-1]
    assert [r[1] for r in per] == shown and total[1] == "**all**"
    assert all(int(r[2]) == int(r[3]) + int(r[4]) + int(r[5]) == 1 for r in per)
    testable = sum(int(r[3]) for r in per)
    assert total[2] == "2" and total[3].startswith(f"{testable} ({testable / 2:.0%}")
    assert {r[1]: r[3] for r in per}["ambient_coupling"] == "0"  # nested in every auto baseline
