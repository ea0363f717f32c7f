"""The private-path probe (benchmarks/probe_private_path.py): a drift residual that follows a lagged driver is
explained out of sample, blocks without the driver carry no evidence, and a residual unrelated to it is not."""

from pathlib import Path

import numpy as np

from thermodrift.core.physics.sensors import first_order_lag

from support import load_file

PROBE = Path(__file__).resolve().parent.parent / "benchmarks" / "probe_private_path.py"


def _case(rng, follows: bool):
    """10 fitted blocks of 60 samples at 120 s and a final block; the driver (W) is on in blocks 2, 5, 7 and in
    the final block; the residual (µm) is 0.01 µm/W through a 0.25 h lag, or not, plus 0.05 µm of noise."""
    probe = load_file(PROBE)
    n, nb = 60, 10
    on = np.zeros(n * (nb + 1))
    for b in (2, 5, 7, nb):
        on[b * n:b * n + n // 2] = 100.0
    x = first_order_lag(on, 120.0 * np.arange(len(on)), 0.25 * 3600.0)
    residual = (0.01 * x if follows else 0.0) + rng.normal(0, 0.05, len(on))
    rows = np.arange(n * nb)
    return probe, residual, x, rows, rows // n, np.arange(n * nb, n * (nb + 1))


def test_a_residual_that_follows_the_lagged_driver_is_explained_on_the_final_block():
    probe, residual, x, rows, blocks, final = _case(np.random.default_rng(0), follows=True)
    r = probe.path_gain(residual, x, rows, blocks, final)
    assert r["final_after"] < 0.3 * r["final_before"]
    assert r["active"] < r["blocks"] and r["active_wins"] == 1.0 and r["active_t"] > 3.0
    assert r["wins"] < 1.0  # blocks where the driver rests carry no evidence either way


def test_a_residual_unrelated_to_the_driver_is_not():
    probe, residual, x, rows, blocks, final = _case(np.random.default_rng(1), follows=False)
    r = probe.path_gain(residual, x, rows, blocks, final)
    assert r["final_after"] > 0.9 * r["final_before"] and r["active_wins"] < 1.0
