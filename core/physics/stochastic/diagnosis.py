"""``thermodrift diagnose --network building_ti``: a building's structure by forward selection (:mod:`.selection`),
its report and figures.

``report.json``::

    {"kind": "stochastic_selection", "network": "building_ti", "alpha": 0.05,
     "selection_path": [{"name": "Ti", "loglik", "n_params", "lr", "df", "p_value", "accepted",
                         "whiteness": {"acf_lag1", "acf_outside", "cp_max_dev", "cp_bound", "white", ...},
                         "candidates": [{"name", "loglik", "n_params"}], "seconds"}, ...],
     "selected": "TiTeTh", "estimates": [{"name", "estimate", "ci95", "unit", "identifiable"}],
     "unidentifiable": {name: why}, "htc": {"value", "ci95", "unit"},
     "one_step": {"rmse_K", "whiteness"}, "k_step": {"k", "horizon_h", "rmse_K", "rmse_K_one_state"},
     "units": {...}, "seconds", "command"}

The first path entry is the one-state model; each later entry is the best extension of the entry before it,
``accepted`` when its LR test passes (the last entry is the rejected one where the selection stopped, if any).
Figures: ``residuals.png`` (one-step residuals and their ACF), ``cumulated_periodogram.png`` (with its 95 %
Kolmogorov–Smirnov band) and ``k_step.png`` (measured, one-step and ``horizon_h``-ahead predictions).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from thermodrift.core import metrics
from thermodrift.core.errors import InputError
from thermodrift.core.physics.stochastic import kalman, whiteness
from thermodrift.core.physics.stochastic.building import htc
from thermodrift.core.physics.stochastic.rc import RCNetwork
from thermodrift.core.physics.stochastic.sde import Series
from thermodrift.core.physics.stochastic.selection import ALPHA, Selection, forward_select

HORIZON_H = 24.0


def _columns(recording, role: str) -> list[str]:
    return [str(c) for c in recording.data.columns if recording.channels[c].role == role]


def series_of(recording, net: RCNetwork, target: str | None = None) -> tuple[Series, str]:
    """The recording as the network's data: time in the network's unit, inputs by role in the network's input
    order, the measured temperature (``target`` or the only channel of role ``temperature``)."""
    cols = []
    for name, role, _ in net.inputs:
        found = _columns(recording, role)
        if not found:
            raise InputError(f"the recording has no {role} channel, which network {net.name!r} needs for its "
                             f"input {name!r}", hint=f"give a channel role: {role} in the manifest")
        cols.append(found[0])
    temps = _columns(recording, "temperature")
    if target is None:
        if len(temps) != 1:
            raise InputError(f"the recording has {len(temps)} temperature channels; the building model measures "
                             "one", hint="name it with --targets")
        target = temps[0]
    elif target not in temps:
        raise InputError(f"--targets {target!r} is not a temperature channel of the recording",
                         hint=f"temperature channels: {', '.join(temps) or 'none'}")
    t = recording.data.index.to_numpy(dtype=float) / net.time_unit_s
    return Series.of(t, recording.data[cols].to_numpy(dtype=float), recording.data[[target]].to_numpy(dtype=float)
                     ), target


def _htc_unit(recording, net: RCNetwork) -> str:
    unit = recording.channels[_columns(recording, "heating")[0]].unit if net.has_input("heating") else None
    return f"{unit}/K" if unit and unit != "1" else "heating-signal units per K"


def select(recording, net: RCNetwork, *, seed: int = 0, alpha: float = ALPHA, starts: int = 2,
           target: str | None = None, progress=None, workers: int = 1, only=None) -> tuple[Selection, Series, str]:
    """Forward selection on a recording (see :func:`.selection.forward_select`)."""
    data, target = series_of(recording, net, target)
    if len(data) < 50:
        raise InputError(f"the recording has {len(data)} rows; stochastic identification needs at least 50")
    return forward_select(net, data, seed=seed, starts=starts, alpha=alpha, progress=progress, workers=workers,
                          only=only), data, target


def report(sel: Selection, data: Series, recording, net: RCNetwork, target: str, out: Path,
           command: str = "") -> dict:
    """Write ``report.json``, ``report.md`` and the figures into ``out``; return the report."""
    out.mkdir(parents=True, exist_ok=True)
    est = sel.selected.estimate
    f = est.filtered()
    dt = float(np.median(np.diff(data.t)))
    k = max(int(round(HORIZON_H / dt)), 1)
    yk = kalman.k_step(est.system, data, f, k)
    first = sel.path[0].estimate
    yk1 = kalman.k_step(first.system, data, first.filtered(), k)
    ok = ~np.isnan(yk[:, 0])
    rmse = lambda p: float(metrics.rmse(data.y[ok, 0], p[ok, 0]))  # noqa: E731  (the first k rows have none)
    value, ci = est.derived(lambda v: htc(est.model, v))
    doc = {
        "kind": "stochastic_selection", "network": net.name, "target": target, "alpha": sel.alpha,
        "selection_path": [s.record() for s in sel.path], "selected": sel.selected.name,
        "estimates": est.table(), "unidentifiable": est.unidentifiable,
        "htc": {"value": value, "ci95": list(ci) if ci else None, "unit": _htc_unit(recording, net)},
        "one_step": {"rmse_K": float(metrics.rms(f.e[:, 0])),
                     "whiteness": whiteness.summary(f.standardized[:, 0])},
        "k_step": {"k": k, "horizon_h": k * dt, "rmse_K": rmse(yk), "rmse_K_one_state": rmse(yk1)},
        "units": {"time": f"{net.time_unit_s:g} s", "temperature": "degC",
                  **{name: recording.channels[_columns(recording, role)[0]].unit for name, role, _ in net.inputs}},
        "seconds": round(sel.seconds, 1), "command": command,
    }
    (out / "report.json").write_text(json.dumps(_plain(doc), indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    (out / "report.md").write_text(_markdown(doc), encoding="utf-8")
    _figures(data, f, yk, k * dt, doc, out)
    return doc


def _plain(x):
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _markdown(doc: dict) -> str:
    lines = [f"# Structure of {doc['target']}: {doc['selected']}", "",
             f"Forward selection from `{doc['network']}`, likelihood-ratio tests at α = {doc['alpha']}.", "",
             "| step | log L | params | LR | p | white |", "|---|---|---|---|---|---|"]
    for s in doc["selection_path"]:
        lr = "" if s["lr"] is None else f"{s['lr']:.1f}"
        p = "" if s["p_value"] is None else f"{s['p_value']:.3g}"
        tag = "" if s["accepted"] else " (rejected)"
        lines.append(f"| {s['name']}{tag} | {s['loglik']:.1f} | {s['n_params']} | {lr} | {p} | "
                     f"{'yes' if s['whiteness']['white'] else 'no'} |")
    h = doc["htc"]
    ci = f" [{h['ci95'][0]:.4g}, {h['ci95'][1]:.4g}]" if h["ci95"] else ""
    lines += ["", f"HTC {h['value']:.4g}{ci} {h['unit']}.", "", "| parameter | estimate | 95 % interval | unit |",
              "|---|---|---|---|"]
    for r in doc["estimates"]:
        lo, hi = r["ci95"]
        note = "" if r["identifiable"] else f" (not identifiable: {r['why']})"
        lines.append(f"| {r['name']} | {r['estimate']:.4g} | [{lo:.4g}, {hi:.4g}]{note} | {r['unit']} |")
    ks = doc["k_step"]
    lines += ["", f"{ks['horizon_h']:g} h-ahead RMSE {ks['rmse_K']:.3f} K (one-state model "
                  f"{ks['rmse_K_one_state']:.3f} K); one-step RMSE {doc['one_step']['rmse_K']:.3f} K.", ""]
    return "\n".join(lines)


def _figures(data: Series, f: kalman.Filtered, yk: np.ndarray, horizon_h: float, doc: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = data.t - data.t[0]
    fig, ax = plt.subplots(2, 1, figsize=(10, 6))
    ax[0].plot(t, f.e[:, 0], lw=0.6)
    ax[0].set(xlabel="time (h)", ylabel="one-step residual (K)", title=f"{doc['selected']}: one-step residuals")
    r = whiteness.acf(f.standardized[:, 0], 96)
    ax[1].bar(np.arange(1, len(r) + 1), r, width=0.8)
    b = 1.96 / math.sqrt(len(data))
    ax[1].axhline(b, ls="--", c="k")
    ax[1].axhline(-b, ls="--", c="k")
    ax[1].set(xlabel="lag (samples)", ylabel="ACF")
    fig.tight_layout()
    fig.savefig(out / "residuals.png", dpi=110)
    plt.close(fig)
    freq, C, ks = whiteness.cumulated_periodogram(f.standardized[:, 0])
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.plot(freq, C, label=doc["selected"])
    ax.plot(freq, freq / 0.5, "k-", lw=0.8)
    ax.plot(freq, np.clip(freq / 0.5 + ks, 0, 1), "k--", lw=0.8, label="95 % KS band")
    ax.plot(freq, np.clip(freq / 0.5 - ks, 0, 1), "k--", lw=0.8)
    ax.set(xlabel="frequency (cycles per sample)", ylabel="cumulated periodogram", title="one-step residuals")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "cumulated_periodogram.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(10, 4))
    ax.plot(t, data.y[:, 0], "k", lw=0.8, label="measured")
    ax.plot(t, data.y[:, 0] - f.e[:, 0], lw=0.6, label="one step ahead")
    ax.plot(t, yk[:, 0], lw=0.8, label=f"{horizon_h:g} h ahead")
    ax.set(xlabel="time (h)", ylabel="temperature (°C)", title=f"{doc['selected']}: predictions")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "k_step.png", dpi=110)
    plt.close(fig)
