"""The diagnose benchmark's side-by-side table: the stochastic mode's top-1 and null counts come from its own
fields, not the output-error mode's, and ``--stochastic`` is refused without an independent generator."""

import sys
from pathlib import Path

import pytest
from support import load_file

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCH))
BENCHMARK = load_file(BENCH / "bench_diagnose.py")
SIDE = load_file(BENCH / "diagnose_stochastic.py")


def _row(hidden, oe, st):
    return {"case": f"fd_{hidden}_1", "hidden": hidden, "top1": oe[0] if oe else "none", "found": oe,
            "findings": len(oe), "seconds": 10.0, "st_top1": st[0] if st else "none", "st_found": st,
            "st_seconds": 30.0, "st_why_not_hidden": "not significant: LR 1.0", "st_verdict": ""}


def test_the_two_modes_are_counted_apart():
    cc, ac = "coolant_coupling", "ambient_coupling"
    rows = [_row(cc, [cc], [ac, cc]), _row(ac, [], [ac]), _row("none", [], [cc]), _row("none", [ac], [])]
    out = SIDE.report(rows)
    assert "| top-1 accuracy, hidden cases | 1/2 = 50% | 1/2 = 50% |" in out
    assert "| hidden named anywhere among the findings | 1/2 = 50% | 2/2 = 100% |" in out
    assert "| null cases with a finding | 1/2 | 1/2 |" in out
    assert SIDE.report([{k: v for k, v in r.items() if not k.startswith("st_")} for r in rows]) == ""


def test_stochastic_needs_an_independent_generator(capsys):
    with pytest.raises(SystemExit) as err:
        BENCHMARK.main(["--stochastic"])
    assert err.value.code == 2 and "--stochastic" in capsys.readouterr().err
