"""The diagnose benchmark's report on independent-generator rows: the held-out cut per pass over the half counts
the hidden cases of that pass only, never the two run-time cases at 15 s (seeds 900 and 901 of the half)."""

import argparse
import sys
from pathlib import Path

from support import load_file

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCH))
BENCHMARK = load_file(BENCH / "bench_diagnose.py")


def _row(seed, hidden, top1, cut, samples=901):
    return {"case": f"fd_{hidden}_{seed}", "seed": seed, "hidden": hidden, "top1": top1,
            "findings": int(top1 != "none"), "seconds": 5.0, "cut": cut, "cut_excess": cut, "samples": samples,
            "share": 0.3, "equivalent": False, "param_error": None, "localisation": None, "cut_channel": "disp_z_um",
            "misfit_over_noise": 2.0, "heldout_over_fit": 1.0, "acf1": 0.5, "why_not_hidden": "", "confidence": None}


def test_the_cut_per_pass_leaves_out_the_run_time_cases():
    cc = "coolant_coupling"
    rows = [_row(9001, cc, cc, 0.5), _row(9012, cc, cc, 0.2), _row(9500, "none", "none", 0.0),
            _row(9900, cc, cc, -0.9, samples=7201)]
    out = BENCHMARK.report(rows, [], argparse.Namespace(generator="fd"))
    passes = [line for line in out.splitlines() if "of pass" in line]
    assert len(passes) == 2
    head = "| held-out cut, median over correct finds of pass"
    assert passes[0].startswith(f"{head} 1 (seeds 0–10") and "| 50% |" in passes[0]
    assert passes[1].startswith(f"{head} 2 (seeds 11–21") and "| 20% |" in passes[1]
    assert "3/3" in out  # the run-time case still counts in top-1
