"""The hidden-start probe (benchmarks/probe_hidden_starts.py): it keeps the set the adequacy step's rule keeps, and
it scores every hidden set from a given start on the inner validation block as that step does."""

from pathlib import Path

import numpy as np

from thermodrift.core import physics
from thermodrift.core.physics.diagnose import adequacy
from thermodrift.core.physics.diagnose.concealed import concealed_case

from support import load_file

PROBE = load_file(Path(__file__).resolve().parent.parent / "benchmarks" / "probe_hidden_starts.py")


def _rows(*held_out):
    return [{"hidden": len(h), "held_out": e} for h, e in zip(adequacy.HIDDEN_OPTIONS, held_out)]


def test_a_larger_set_is_kept_only_when_it_beats_the_kept_one_by_the_minimum_gain():
    gain = adequacy.MIN_GAIN
    assert PROBE.kept(_rows(1.0, 1.0 - gain / 2, 1.0 - gain / 2)) == 2
    assert PROBE.kept(_rows(1.0, 0.5, 0.5 * (1 - gain / 2))) == 3
    assert PROBE.kept(_rows(1.0, 2.0, 0.5)) == 4


def test_every_hidden_set_is_scored_from_the_declared_and_a_jittered_start():
    case = concealed_case(physics.load_network("demo_spindle"), None, 4, hours=14.0, dt_s=120.0)
    declared = PROBE.held_out_errors(case.recording, None, evaluations=20)
    jittered = PROBE.held_out_errors(case.recording, 1, evaluations=20)
    assert [r["hidden"] for r in declared] == [len(h) for h in adequacy.HIDDEN_OPTIONS]
    for rows in (declared, jittered):
        assert all(np.isfinite(r["held_out"]) and r["held_out"] > 0 and r["fitted"] > 0 for r in rows)
    assert any(d["fitted"] != j["fitted"] for d, j in zip(declared, jittered))  # another start, another search
