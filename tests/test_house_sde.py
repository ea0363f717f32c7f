"""The independent house simulator: its structures, its steady state and its Euler–Maruyama route."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from benchmarks.independent import house_sde


def test_library_has_every_structure_once():
    names = house_sde.structures()
    assert len(names) == len(set(names)) == 24           # 16 state subsets + 8 with an envelope and AeRia
    for name in names:
        states, aeria = house_sde.parse(name)
        assert "".join(states) + ("AeRia" if aeria else "") == name
    for bad in ("TiAeRia", "TeTi", "TiTx", ""):
        with pytest.raises(ValueError):
            house_sde.parse(bad)


@pytest.mark.parametrize("structure", house_sde.structures())
def test_steady_gain_of_heat_is_the_inverse_htc(structure):
    """1 kW of heat held for ever raises the reading by 1/HTC kelvin, and the ambient passes with gain 1."""
    house = house_sde.draw_house(structure, np.random.default_rng(7))
    A, B, _, c = house.matrices()
    gain = -c @ np.linalg.solve(A, B)
    assert gain[0] == pytest.approx(1.0, rel=1e-9)
    assert gain[2] == pytest.approx(1.0 / house.htc, rel=1e-9)
    assert 0.05 <= house.htc <= 0.4
    assert np.all(np.linalg.eigvals(A).real < 0)


def test_euler_maruyama_without_noise_meets_the_exact_discretisation():
    house = house_sde.draw_house("TiTeTh", np.random.default_rng(3))
    house.params.update({k: 0.0 for k in house.params if k.startswith("sigma_")})
    house.meas_sd = 0.0
    df = house_sde.simulate(house, days=2.0, seed=5, step_s=10.0)
    A, B, _, c = house.matrices()
    n = len(A)
    M = expm(np.block([[A, B], [np.zeros((3, n + 3))]]) * house_sde.SAMPLE_H)
    Ad, Bd = M[:n, :n], M[:n, n:]
    x = np.linalg.solve(A, -B @ [df.Ta[0], 0.0, 0.0])
    x = x + house.setpoint[0] - c @ x                   # the documented start: steady, at the day set-point
    y = []
    for k in range(len(df)):
        y.append(c @ x)
        x = Ad @ x + Bd @ df[["Ta", "Ps", "Thm"]].to_numpy()[k]
    assert np.max(np.abs(np.array(y) - df.yTi.to_numpy())) < 0.01


def test_same_seed_same_recording_and_the_halves_are_disjoint():
    a = house_sde.make_case(11, "TiTs", days=1.0)[1]
    b = house_sde.make_case(11, "TiTs", days=1.0)[1]
    assert a.equals(b)
    assert not a.equals(house_sde.make_case(12, "TiTs", days=1.0)[1])
    dev = {s for s, _ in house_sde.case_list(False, 30)}
    sealed = {s for s, _ in house_sde.case_list(True, 30)}
    assert not dev & sealed and min(sealed) >= house_sde.SEALED_FROM


def test_recording_is_a_plausible_winter_house():
    house, df = house_sde.make_case(2, "TiTeAeRia", days=10.0)
    assert list(df.columns) == ["t", "Ta", "Ps", "Thm", "yTi"]
    assert len(df) == 10 * 96 and (df.t.diff().dropna() == df.t.diff().iloc[1]).all()
    assert 0.0 <= df.Ps.min() and df.Ps.max() <= 0.4 and (df.Ps == 0).mean() > 0.5     # nights
    assert 0.2 < (df.Thm > 0).mean() < 1.0 and df.Thm.max() <= house.heater_kw
    assert 14.0 < df.yTi.median() < 24.0
