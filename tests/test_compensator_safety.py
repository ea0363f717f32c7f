"""Fault injection on the compensator: whatever the inputs do, the written value moves by at most the rate limit,
stays inside the clamp, is never computed from a failed input, and the audit names the sensor and the reason."""

import io
import json

import numpy as np
import pytest

from thermodrift import compensator
from thermodrift.compensator import guard, limits, package
from thermodrift.compensator.audit import Audit
from thermodrift.core import deployment, registry
from thermodrift.core.study import model_inputs
from thermodrift.testing.data import tiny_recording

CUT = 150  # replay from this row on (the model is fitted on every row: the tiny recording's last block runs at
# a speed the first rows never reach, so its temperatures lie outside any earlier training range)


def fitted(name: str):
    rec = tiny_recording(seed=0)
    targets, temps = rec.columns("displacement"), rec.columns("temperature")
    cls = registry.get("model", name).factory
    X, y = model_inputs(rec, temps, cls, targets), rec.data[targets]
    return registry.create("model", name).fit(X, y), X, y


def export(model, X, y, folder, fallbacks=None):
    lim = limits.training_limits(X.to_numpy(), list(X.columns), y.to_numpy(), list(y.columns),
                                 X.index.to_numpy())
    package.write(package.document(model.export_state(), lim, fallbacks=fallbacks), folder)
    return compensator.load(folder)


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    model, X, y = fitted("mlr")
    fb = deployment.fallbacks(model, X, y.loc[X.index], 60.0)
    pkg = export(model, X, y, tmp_path_factory.mktemp("pkg"), fallbacks=fb)
    return model, X, pkg


def replay(pkg, times, rows, **options):
    comp = pkg.compensator(**options)
    buf = io.StringIO()
    audit = Audit(buf, pkg, comp)
    steps = []
    for t, v in zip(times, rows):
        steps.append(comp.update(t, v))
        audit.write(steps[-1], v)
    return comp, steps, [json.loads(line) for line in buf.getvalue().splitlines()]


def faults(X, pkg):
    """(name, times, rows, sensor, reason) for each injected fault on the held-out rows."""
    rows = X[pkg.inputs].to_numpy()[CUT:].copy()
    times = X.index.to_numpy()[CUT:].astype(float)
    j = pkg.inputs.index("T_front_bearing")
    span = pkg.limits["inputs"]["T_front_bearing"]["max"] - pkg.limits["inputs"]["T_front_bearing"]["min"]
    nan = rows.copy(); nan[30:40, j] = np.nan
    stuck = rows.copy(); stuck[20:90, j] = stuck[20, j]
    spike = rows.copy(); spike[50, j] += 2 * pkg.safety["jump"]["T_front_bearing"]  # within the range margin
    drift = rows.copy(); drift[:, j] += np.linspace(0, 3 * span, len(drift))
    out = [("nan", times, nan, "T_front_bearing", "missing"), ("stuck", times, stuck, "T_front_bearing", "stuck"),
           ("spike", times, spike, "T_front_bearing", "jump"),
           ("drift", times, drift, "T_front_bearing", "out_of_range")]
    keep = np.ones(len(rows), bool); keep[40] = False
    out.append(("missing_row", times[keep], rows[keep], "time", "time_gap"))
    jump = times.copy(); jump[60:] += 3600.0
    out.append(("time_jump", jump, rows, "time", "time_gap"))
    back = times.copy(); back[70] = back[69]
    out.append(("time_repeat", back, rows, "time", "time_not_increasing"))
    return out


@pytest.mark.parametrize("case", range(7))
def test_written_values_respect_limits_and_the_audit_names_the_fault(setup, case):
    model, X, pkg = setup
    name, times, rows, sensor, reason = faults(X, pkg)[case]
    comp, steps, lines = replay(pkg, times, rows, max_step_um=0.5)
    written = np.array([s.written for s in steps])
    assert np.isfinite(written).all()
    assert np.abs(np.diff(written, axis=0)).max() <= 0.5 + 1e-12
    assert (np.abs(written) <= comp.clamp + 1e-12).all()
    flagged = [ln for ln in lines if {"sensor": sensor, "reason": reason} in ln["reasons"]]
    assert flagged, name
    assert len(lines) == len(steps) and all(set(ln) >= {"inputs", "raw_um", "written_um", "limits", "reasons"}
                                            for ln in lines)
    for ln, step in zip(lines, steps):  # a row with a failed sensor is never written from the main model
        failed = [r for r in ln["reasons"] if "sensor" in r and r["sensor"] != "time"]
        if failed:
            assert step.source != "model" and set(ln["status"].values()) <= {"held", "fallback"}


def test_a_dead_sensor_switches_to_its_fallback_and_back(setup):
    model, X, pkg = setup
    rows = X[pkg.inputs].to_numpy()[CUT:].copy()
    times = X.index.to_numpy()[CUT:].astype(float)
    j = pkg.inputs.index("T_column")
    rows[10:30, j] = np.nan
    comp, steps, _ = replay(pkg, times, rows, clamp_um=1e6, max_step_um=1e6)
    assert [s.source for s in steps[10:30]] == ["fallback:T_column"] * 20
    assert all(s.source == "model" for s in steps[30:])
    fb = pkg.fallbacks["T_column"]["state"]
    keep = [pkg.inputs.index(c) for c in fb["inputs"]]
    expected = ((rows[10:30][:, keep] - fb["mean"]) / fb["scale"]) @ fb["coef"] + fb["intercept"]
    assert np.allclose([s.written for s in steps[10:30]], expected, atol=1e-9)


def test_without_a_fallback_the_last_value_is_held(setup):
    model, X, pkg = setup
    rows = X[pkg.inputs].to_numpy()[CUT:].copy()
    rows[10:20, :2] = np.nan  # two sensors at once: no fallback covers that
    comp, steps, _ = replay(pkg, X.index.to_numpy()[CUT:].astype(float), rows)
    assert all(s.source == "hold" for s in steps[10:20])
    assert all((s.written == steps[9].written).all() for s in steps[10:20])


def test_no_limits_writes_the_prediction_and_reports_what_would_have_applied(setup):
    model, X, pkg = setup
    name, times, rows, *_ = faults(X, pkg)[2]  # the spike
    comp, steps, lines = replay(pkg, times, rows, limits=False, max_step_um=0.5)
    import pandas as pd

    frame = pd.DataFrame(rows, columns=pkg.inputs, index=times)
    expected = model.predict(frame[list(model.feature_names_in_)])
    assert np.abs(np.array([s.written for s in steps]) - expected).max() <= 1e-9
    statuses = [guard.STATUSES[c] for s in steps for c in s.status]
    assert "held" in statuses or "fallback" in statuses  # the spike row, reported, not applied
    assert "rate_limited" in statuses


def test_status_is_the_most_severe_that_applied(setup):
    model, X, pkg = setup
    rows = X[pkg.inputs].to_numpy()[CUT:CUT + 5].copy()  # 5 rows
    times = X.index.to_numpy()[CUT:CUT + 5].astype(float)
    comp, steps, _ = replay(pkg, times, rows, max_step_um=1e-6, clamp_um=1e-7)
    assert all(guard.STATUSES[c] == "clamped" for s in steps[1:] for c in s.status)  # clamped beats rate_limited
    assert np.abs(np.array([s.written for s in steps])).max() <= 1e-7


def test_probes_remove_a_constant_bias(setup):
    model, X, pkg = setup
    rows = X[pkg.inputs].to_numpy()[CUT:]
    times = X.index.to_numpy()[CUT:].astype(float)
    truth = model.predict(X.iloc[CUT:]) + 5.0  # the machine drifts 5 µm more than the model says
    probes = [(times[i], 0, truth[i, 0]) for i in (0, 30, 60)]
    comp, steps, lines = replay(pkg, times, rows, limits=False, probes=probes)
    err_after = np.abs(np.array([s.written[0] for s in steps[61:]]) - truth[61:, 0])
    assert err_after.max() < 0.5 and "bias_um" in lines[-1]
