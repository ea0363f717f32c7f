"""The hidden-start probe (benchmarks/probe_hidden_starts.py) and the adequacy step's ``jitter_seed``: every hidden
set is scored on the inner validation block from the declared or a jittered start, a jittered start searches from
elsewhere, and the set kept is the one the rule keeps on that table."""

from pathlib import Path

import numpy as np
import pytest

from thermodrift.core import physics
from thermodrift.core.physics.diagnose import adequacy
from thermodrift.core.physics.diagnose.concealed import concealed_case

from support import load_file

PROBE = load_file(Path(__file__).resolve().parent.parent / "benchmarks" / "probe_hidden_starts.py")


@pytest.fixture(scope="module")
def tables():
    case = concealed_case(physics.load_network("demo_spindle"), None, 4, hours=14.0, dt_s=120.0)
    return [PROBE.hidden_table(case.recording, seed, evaluations=20) for seed in (None, 1)]


def _kept_by_rule(table) -> int:
    best = table[0]
    for row in table[1:]:
        if row["heldout_error"] < (1 - adequacy.MIN_GAIN) * best["heldout_error"]:
            best = row
    return best["hidden_nodes"]


def test_every_hidden_set_is_scored_from_either_start(tables):
    for kept, table in tables:
        assert [r["hidden_nodes"] for r in table] == [len(h) for h in adequacy.HIDDEN_OPTIONS]
        assert all(np.isfinite(r["heldout_error"]) and r["heldout_error"] > 0 and r["fitted_error"] > 0
                   for r in table)
        assert kept == _kept_by_rule(table)
        assert [r["chosen"] for r in table].count(True) == 1


def test_a_jittered_start_searches_from_elsewhere(tables):
    (_, declared), (_, jittered) = tables
    assert any(d["fitted_error"] != j["fitted_error"] for d, j in zip(declared, jittered))
