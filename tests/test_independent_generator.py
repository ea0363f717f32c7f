"""The independent concealed-effect generator (benchmarks/independent): physics, seeds, file format."""

from __future__ import annotations

import ast
import copy
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import independent  # noqa: E402
from independent import fd_model, planted  # noqa: E402
from independent.programme import Chiller, Programme  # noqa: E402


def _machine(seed: int = 3, block: bool = False):
    m = fd_model.build(np.random.default_rng(seed), block=block)
    m.info["n_max"] = 10000.0
    return m


def _constant_programme(hours: float, h: float, speed: float) -> Programme:
    t = np.arange(int(hours * 3600 / h) + 1) * h
    return Programme(t, h, np.full(len(t), speed), np.zeros(len(t)), np.zeros(len(t)), 10000.0)


def test_machine_has_at_least_40_nodes_in_shaft_housing_column_and_bed():
    m = _machine(block=True)
    parts = ("shaft", "housing", "column_front", "column_back", "bed")
    assert sum(m.seg(p).n for p in parts) >= 40
    assert m.size == sum(s.n for s in m.segments.values())
    assert np.allclose(m.K, m.K.T) and np.allclose(m.K.sum(axis=1), 0.0)  # joints conserve heat


def test_insulated_machine_conserves_energy():
    m = _machine()
    m.g_air[:] = 0.0
    m.g_floor[:] = 0.0
    prog = _constant_programme(3.0, 60.0, 8000.0)
    res = fd_model.simulate(m, prog, np.full(len(prog.t), 20.0), 20.0, None, fd_model.Effect())
    q = fd_model.base_heat(m, 8000.0).sum()
    stored = (m.C * (res.T[-1] - res.T[0])).sum()
    assert stored == pytest.approx(q * prog.t[-1], rel=1e-9)


def test_constant_run_reaches_the_steady_state():
    m = _machine()
    prog = _constant_programme(400.0, 600.0, 6000.0)
    res = fd_model.simulate(m, prog, np.full(len(prog.t), 21.0), 19.0, None, fd_model.Effect())
    steady = fd_model.steady_state(m, fd_model.base_heat(m, 6000.0), 21.0, 19.0)
    assert np.abs(res.T[-1] - steady).max() < 1e-3
    assert steady.max() > 25.0  # the spindle does warm


def test_conduction_grid_matches_the_analytic_bar_conductance():
    m = _machine()
    col = m.seg("column_front")
    K = m.K[np.ix_(col.idx, col.idx)].copy()
    # heat flowing along the bar alone (the web to the back face removed) from its first to its last volume
    K -= np.diag(K.sum(axis=1))
    K[0, 0] += 1.0  # hold the first volume through a unit conductance to 0 K
    q = np.zeros(col.n)
    q[-1] = 1.0
    T = np.linalg.solve(K, q)
    g_bar = col.mat["k"] * col.area / ((col.n - 1) * col.dx)
    assert 1.0 / (T[-1] - T[0]) == pytest.approx(g_bar, rel=1e-9)


def test_chiller_cycles_within_its_hysteresis_band():
    c = Chiller(20.0, 1.0, 3e5, 1500.0, 80.0, 5.0, steady=False, tank=20.0)
    temps, states = [], []
    for _ in range(4 * 3600 // 15):
        c.step(300.0, 22.0, 15.0)
        temps.append(c.tank)
        states.append(c.on)
    temps = np.array(temps[len(temps) // 4:])
    assert temps.min() > 19.4 and temps.max() < 20.6
    assert np.sum(np.diff(np.array(states, dtype=int)) == 1) >= 3  # the compressor cycles


def test_dev_and_sealed_seeds_are_disjoint_and_cover_every_mechanism():
    dev = independent.case_list(False, 3, 20)
    sealed = independent.case_list(True, 3, 20)
    assert {s for s, _, _ in dev}.isdisjoint({s for s, _, _ in sealed})
    assert all(s < independent.SEALED_FROM for s, _, _ in dev)
    assert all(s >= independent.SEALED_FROM for s, _, _ in sealed)
    hidden = [h for _, h, _ in sealed if h]
    assert len(hidden) >= 30 and all(hidden.count(m) >= 2 for m in independent.HIDDEN)
    assert sum(h is None for _, h, _ in sealed) >= 20
    fresh = independent.case_list(True, 3, 20, base=3000)  # a fresh sealed range: disjoint from both
    seeds = {s for s, _, _ in fresh}
    assert seeds.isdisjoint({s for s, _, _ in dev} | {s for s, _, _ in sealed}) and min(seeds) == 3000
    assert [h for _, h, _ in fresh] == [h for _, h, _ in sealed]


def test_generator_shares_no_code_with_the_library():
    for path in (ROOT / "benchmarks" / "independent").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not any(n.startswith(("thermodrift", "plugins")) for n in names), path.name


def test_case_is_deterministic_loads_through_the_manifest_and_plants_its_share(tmp_path):
    from thermodrift.core.recording import load_recording

    a = independent.make_case(7, "centrifugal_growth", hours=10.0)
    b = independent.make_case(7, "centrifugal_growth", hours=10.0)
    assert a.table.equals(b.table)
    rec = load_recording(*a.write(tmp_path))
    assert rec.speed is not None and rec.columns("displacement") and len(rec.columns("temperature")) >= 3
    assert rec.columns("ambient")
    assert 0.1 < a.share < 0.6 and a.effect_um["disp_z_um"] > 10 * a.info["probe_noise_um"]


def test_null_with_constant_drivers_logs_them_constant():
    g = independent.make_case(independent.NULL_OFFSET + 1, None, hours=6.0, constant_drivers=True)
    assert (g.table["cutting_power_W"] == 0).all() and (g.table["x_feed_mm_min"] == 0).all()
    assert np.ptp(g.table["coolant_inlet_degC"]) < 0.2  # sensor noise around a held set point
    assert g.effect_um == {}


def test_planted_mechanism_changes_the_machine_only_through_its_effect():
    m = _machine()
    prog = _constant_programme(4.0, 60.0, 9000.0)
    air = np.full(len(prog.t), 20.0)
    base = fd_model.simulate(copy.deepcopy(m), prog, air, 20.0, None, fd_model.Effect())
    eff = planted.Centrifugal(np.random.default_rng(0))
    res = fd_model.simulate(copy.deepcopy(m), prog, air, 20.0, None, eff)
    assert np.allclose(res.T, base.T)
    growth = res.drift["z"] - base.drift["z"]
    assert abs(growth[-1]) == pytest.approx((9000.0 / 10000.0) ** 2, rel=1e-3)  # c = ±1 µm at n_max, settled


def test_lumped_generator_draws_another_topology_per_seed():
    tops = []
    for seed in range(6):
        m = fd_model.build(np.random.default_rng(seed), lumped=True)
        assert 10 <= m.size < 20 and np.allclose(m.K, m.K.T)
        tops.append(frozenset(m.info["extra_links"]))
    assert len(set(tops)) >= 3


def test_preload_feedback_stays_bounded_where_its_gain_would_run_away():
    m = _machine()
    m.p = 1.0
    prog = _constant_programme(12.0, 60.0, 10000.0)
    eff = planted.Preload(np.random.default_rng(0))
    eff.scale = 1e3  # κ·scale of 40–100 /K: the unbounded law overflows within the run
    res = fd_model.simulate(copy.deepcopy(m), prog, np.full(len(prog.t), 20.0), 20.0, None, eff)
    assert np.isfinite(res.T).all() and np.isfinite(res.drift["z"]).all()
    T = res.T[-1]
    q = eff.heat(m, T, len(prog.t) - 1, prog)
    top = sum(float(np.sum(m.q_top[k])) for k in ("front_bearing", "rear_bearing"))
    assert 0 < q.sum() <= top * (planted.Preload.MAX_FACTOR - 1) * (1 + 1e-12)
