"""The building RC library (mechanisms building_*), its names and heat-transfer coefficient, forward selection on
a simulated house and ``thermodrift diagnose --network building_ti`` end to end."""

import json

import numpy as np
import pandas as pd
import pytest

from thermodrift.core import registry
from thermodrift.core.errors import InputError
from thermodrift.core.physics import stochastic as sto
from thermodrift.core.physics.stochastic.selection import forward_select

MANIFEST = """time: t
channels:
  Ta: {role: ambient, unit: degC}
  Ps: {role: solar_irradiance, unit: kW/m2}
  Thm: {role: heating, unit: "1"}
  yTi: {role: temperature, unit: degC}
"""


@pytest.fixture(scope="module")
def reg():
    return registry.default()


def extend(net, reg, *ids):
    for i in ids:
        net = reg.create("mechanism", f"building_{i}").apply(net)
    return net


def test_the_library_builds_the_field_structures_by_name(reg):
    ti = sto.load("building_ti")
    assert sto.structure_name(ti) == "Ti" and [p.name for p in ti.params] == ["Ci", "Ria", "Aw", "sigma_ti",
                                                                              "sigma_y"]
    full = extend(ti, reg, "ts", "th", "te", "aeria", "tm")
    assert sto.structure_name(full) == "TiTmTeThTsAeRia"
    assert sorted(full.state_names) == sorted(["Ti", "Tm", "Te", "Th", "Ts"])
    te = extend(ti, reg, "te")
    assert ("Ti", "Ta", "Ria") not in te.couplings and "Ria" not in {p.name for p in te.params}
    assert ("Ti", "Ta", "Ria") in extend(te, reg, "aeria").couplings  # AeRia brings the direct path back
    th = extend(ti, reg, "th")
    assert ("Th", "Phi", "") in th.heat and ("Ti", "Phi", "") not in th.heat
    assert extend(ti, reg, "ts").outputs[0][1] == "Ts"
    assert not reg.get("mechanism", "building_aeria").factory.places(ti)  # AeRia needs the envelope
    with pytest.raises(InputError, match="cannot extend"):
        reg.create("mechanism", "building_aeria").apply(ti)
    with pytest.raises(InputError, match="cannot extend"):
        reg.create("mechanism", "building_te").apply(te)


def test_htc_is_the_steady_loss_per_kelvin_of_each_structure(reg):
    ti = sto.load("building_ti")
    v = ti.values()
    assert sto.htc(ti) == pytest.approx(1 / v["Ria"])
    for part in ("th", "tm", "ts"):  # heater, medium and sensor store heat but do not change the steady loss
        assert sto.htc(extend(ti, reg, part)) == pytest.approx(1 / v["Ria"])
    te = extend(ti, reg, "te")
    w = te.values()
    assert sto.htc(te) == pytest.approx(1 / (w["Rie"] + w["Rea"]))
    full = extend(te, reg, "aeria")
    u = full.values()
    assert sto.htc(full) == pytest.approx(1 / (u["Rie"] + u["Rea"]) + 1 / u["Ria"])


def test_building_mechanisms_have_no_place_on_a_machine_network(reg):
    from thermodrift.core import physics

    demo = physics.load_network("demo_spindle")
    for name in ("ti", "te", "th", "tm", "ts", "aeria"):
        cls = reg.get("mechanism", f"building_{name}").factory
        assert cls.places(demo) == [] and cls.unplaced(demo).startswith("skipped: ")
        with pytest.raises(InputError, match="stochastic building network"):
            cls().apply(demo)


def _weather(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.25
    day = 2 * np.pi * t / 24
    ta = 6 + 3 * np.sin(day - 2) + np.cumsum(rng.normal(0, 0.05, n))
    ps = np.clip(np.sin(day - np.pi / 2), 0, None) * rng.uniform(0.05, 0.3, n // 96 + 1).repeat(96)[:n]
    phi = np.where((np.sin(day * 3 + 0.4) > 0.1) & (np.sin(day) < 0.8), 6.0, 0.0)  # on/off heating, kW
    return t, np.column_stack([ta, ps, phi])


TRUE_TITE = {"Ci": 1.0, "Ria": 5.0, "Aw": 4.0, "sigma_ti": 0.15, "sigma_y": 0.03, "Ce": 8.0, "Rie": 0.8,
             "Rea": 3.0, "sigma_te": 0.1}


def _house(reg, n=700, seed=1):
    net = extend(sto.load("building_ti"), reg, "te")
    t, u = _weather(n, seed)
    y = sto.simulate(net.system({k: TRUE_TITE[k] for k in net.values()}), sto.Series.of(t, u, np.full(n, 19.0)),
                     seed=seed)
    return net, sto.Series.of(t, u, y)


def test_forward_selection_recovers_an_envelope_house_and_its_htc(reg):
    _, data = _house(reg)
    sel = forward_select(sto.load("building_ti"), data, seed=0, starts=1,
                         only=("building_te", "building_th", "building_aeria"))
    names = [s.name for s in sel.path]
    assert names[0] == "Ti" and sel.selected.name == "TiTe", names
    assert sel.path[1].accepted and sel.path[1].p_value < 1e-6
    assert not sel.path[-1].accepted or len(sel.path) == 2
    est = sel.selected.estimate
    value, (lo, hi) = est.derived(lambda v: sto.htc(est.model, v))
    assert lo < 1 / (0.8 + 3.0) < hi and abs(value * 3.8 - 1) < 0.1
    assert sel.path[0].whiteness["white"] is False and sel.selected.whiteness["cp_max_dev"] < \
        sel.path[0].whiteness["cp_max_dev"]


def test_diagnose_cli_selects_a_structure_and_writes_the_report(tmp_path, reg, cli):
    _, data = _house(reg, n=400, seed=2)
    t = pd.date_range("2021-11-01", periods=len(data), freq="15min")
    frame = pd.DataFrame({"t": t.strftime("%Y-%m-%d %H:%M:%S"), "Ps": data.u[:, 1], "Ta": data.u[:, 0],
                          "yTi": data.y[:, 0], "Thm": data.u[:, 2]})
    table, manifest = tmp_path / "blg.csv", tmp_path / "m.yaml"
    frame.to_csv(table, sep=";")
    manifest.write_text(MANIFEST, encoding="utf-8")
    out = tmp_path / "dx"
    proc = cli(tmp_path, "diagnose", str(table), "--manifest", str(manifest), "--network", "building_ti",
               "--mechanisms", "building_te", "building_ts", "--out", str(out), timeout=300)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((out / "report.json").read_text(encoding="utf-8"))
    path = doc["selection_path"]
    assert path[0]["name"] == "Ti" and doc["selected"] in [p["name"] for p in path]
    for step in path:
        assert {"name", "loglik", "n_params", "lr", "p_value", "whiteness"} <= set(step)
        assert {"white", "cp_max_dev", "cp_bound", "acf_outside"} <= set(step["whiteness"])
    assert all(p["loglik"] > path[0]["loglik"] for p in path[1:])
    assert doc["htc"]["unit"] == "heating-signal units per K" and doc["htc"]["ci95"][0] < doc["htc"]["value"]
    assert doc["estimates"] and all(len(r["ci95"]) == 2 for r in doc["estimates"])
    for fig in ("residuals.png", "cumulated_periodogram.png", "k_step.png"):
        assert (out / fig).stat().st_size > 0
    assert "selected " + doc["selected"] in proc.stdout
    bad = cli(tmp_path, "diagnose", str(table), "--manifest", str(manifest), "--network", "building_ti",
              "--alpha", "2", "--out", str(out), timeout=120)
    assert bad.returncode == 2 and "--alpha" in bad.stderr
