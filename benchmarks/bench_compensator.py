"""The compensator against issue 22's "Done means", on the real FL_THERMAL recording (ch3, µm).

Protocol: the project's reference split (``experiment=fl_thermal_5000rpm_heldout``): train on t < 24.13 h
(1250, 2500, 3750 rpm with their cool-downs), replay 24.13 h <= t < 32.13 h (the 5000 rpm run and its
cool-down) one row at a time, the training rows as history. Inputs: the 16 temperatures, plus speed for the
families that read it; untuned defaults (``lptn_hybrid`` with a short calibration and ``lstm`` with a few
epochs, ``tcn_lstm`` (a ``torch.export`` graph) likewise: their accuracy is not what is measured here). Every
model goes through its data-only package.

Tables:
1. ``--no-limits`` equality: max |compensator − predict(X, history)| (µm) over the replay, in-process and
   through ``thermodrift compensate`` (CSV out) for transfer_function.
2. Per-update cost (ms, median and 99th percentile) of ``Compensator.update`` (input checks, fallbacks, limits
   included; no file I/O, no audit), and of the bare runtime streamer.
3. Runtime import time and memory (a fresh interpreter: import thermodrift.compensator, load, one update).
4. Soak: the whole recording (11,115 rows) replayed again and again (times shifted on), limits on, audit off:
   updates, resident memory at 10 % and at the end.
5. Fault injection on one sensor (NaN, stuck, spike, slow drift), a missing row and a time jump: the largest
   written change per update versus the rate limit, the largest |written| versus the clamp, and whether the
   audit names the sensor and the reason.
6. Each used sensor dead for the whole held-out block: RMSE (µm) with its fallback, median and worst over
   sensors, versus the full model.
7. Probe updates (measured ch3 every 30 min, every 2 h): held-out RMSE without and with them.

    python benchmarks/bench_compensator.py              # soak 5 replays (56 k updates); about 5 minutes
    python benchmarks/bench_compensator.py --soak 100   # the issue's 1.1 M updates
"""

from __future__ import annotations

import argparse
import io
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

TARGET = "ch3(um)"
TRAIN_END_H, TEST_END_H = 24.13, 32.13
MODELS = {"mlr": {}, "transfer_function": {}, "lptn_hybrid": {"max_evaluations": 20, "max_fit_samples": 3000},
          "lstm": {"trainer": {"epochs": 4, "t0": 2}}, "tcn_lstm": {"trainer": {"epochs": 2, "t0": 2}}}


NETWORKS = ("lstm", "tcn_lstm")


def rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def setup():
    from thermodrift.core import registry

    rec = registry.create("dataset", "fl_thermal")
    t = rec.time_s
    train = np.flatnonzero(t < TRAIN_END_H * 3600)
    test = np.flatnonzero((t >= TRAIN_END_H * 3600) & (t < TEST_END_H * 3600))
    return rec, train, test


def build(name, rec, train, folder):
    """(model, X, y, package) with limits and fallbacks as `thermodrift run` logs them."""
    import pandas as pd

    from thermodrift import compensator
    from thermodrift.compensator import limits, package
    from thermodrift.core import deployment, registry
    from thermodrift.core.study import model_inputs

    cls = registry.get("model", name).factory
    X = model_inputs(rec, rec.columns("temperature"), cls, [TARGET])
    y = rec.data[[TARGET]]
    model = registry.create("model", name, **MODELS[name]).fit(X.iloc[train], y.iloc[train])
    Xt, yt = X.iloc[train], y.iloc[train]
    lim = limits.training_limits(Xt.to_numpy(), list(X.columns), yt.to_numpy(), [TARGET], Xt.index.to_numpy())
    fb = deployment.fallbacks(model, Xt, yt, lim["sampling_interval_s"])
    package.write(package.document(model.export_state(), lim, fallbacks=fb), folder)
    assert isinstance(X, pd.DataFrame)
    return model, X, y, compensator.load(folder)


def replay(pkg, X, train, rows, values=None, times=None, **options):
    hist = X.iloc[train]
    comp = pkg.compensator(history=hist[pkg.inputs].to_numpy(), history_times_s=hist.index.to_numpy(), **options)
    values = X.iloc[rows][pkg.inputs].to_numpy() if values is None else values
    times = X.index.to_numpy()[rows].astype(float) if times is None else times
    return comp, [comp.update(t, v) for t, v in zip(times, values)]


def rmse(a, b) -> float:
    from thermodrift.core import metrics

    return float(metrics.rmse(a, b))


def table(title, header, rows):
    print(f"\n### {title}\n\n| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    for r in rows:
        print("| " + " | ".join(f"{v:.4g}" if isinstance(v, float) else str(v) for v in r) + " |")


def cli_equality(pkg_dir, rec, test, model, X, train):
    """transfer_function through `thermodrift compensate --no-limits` on the held-out rows (a CSV + manifest)."""
    import pandas as pd
    import yaml

    with tempfile.TemporaryDirectory() as tmp:
        block = rec.data.iloc[test].reset_index()
        block.to_csv(Path(tmp) / "block.csv", index=False)
        manifest = {"time": "time_s", "channels": {c: {"role": ch.role, "unit": ch.unit}
                                                   for c, ch in rec.channels.items() if ch.role != "condition"}}
        (Path(tmp) / "block.yaml").write_text(yaml.safe_dump(manifest, allow_unicode=True), encoding="utf-8")
        out = subprocess.run([sys.executable, "-m", "thermodrift.core.cli", "compensate", str(pkg_dir), "--input",
                              str(Path(tmp) / "block.csv"), "--manifest", str(Path(tmp) / "block.yaml"), "--out",
                              str(Path(tmp) / "v.csv"), "--no-limits"], capture_output=True, text=True)
        if out.returncode:
            return f"failed: {out.stderr.strip()[-200:]}"
        got = pd.read_csv(Path(tmp) / "v.csv")[f"{TARGET}_um"].to_numpy()
    # the CLI starts without history: compare with predict from the block's first row
    return float(np.abs(got - model.predict(X.iloc[test])[:, 0]).max())


def import_cost(pkg_dir) -> tuple[float, float, list[str]]:
    """(s to import the runtime, load the package and run one update; resident MB that adds to an interpreter
    with numpy; heavy modules loaded) in a fresh interpreter."""
    code = ("import os, sys, time; import numpy as np\n"
            "rss = lambda: int(open('/proc/self/statm').read().split()[1]) * os.sysconf('SC_PAGE_SIZE') / 2**20\n"
            "r0 = rss(); t = time.perf_counter(); import thermodrift.compensator as c; p = c.load(sys.argv[1])\n"
            "s = p.compensator(); s.update(0.0, np.full(len(p.inputs), 20.0))\n"
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'torch', 'pandas', 'sklearn', "
            "'mlflow', 'optuna'} | {m for m in sys.modules if m.startswith('thermodrift.core')})\n"
            "print(time.perf_counter() - t, rss() - r0, ','.join(heavy) or '-')")
    out = subprocess.run([sys.executable, "-c", code, str(pkg_dir)], capture_output=True, text=True, check=True)
    s, mb, heavy = out.stdout.split()
    return float(s), float(mb), heavy


def faults(pkg, X, train, test, y):
    """Fault injection on the hottest sensor the model reads, plus a missing row and a time jump."""
    from thermodrift.compensator.audit import Audit

    values = X.iloc[test][pkg.inputs].to_numpy()
    times = X.index.to_numpy()[test].astype(float)
    sensor = max((c for c in pkg.inputs if c.startswith("t")), key=lambda c: pkg.limits["inputs"][c]["max"])
    j = pkg.inputs.index(sensor)
    span = pkg.limits["inputs"][sensor]["max"] - pkg.limits["inputs"][sensor]["min"]
    n = len(values)
    cases = {}
    v = values.copy(); v[100:140, j] = np.nan; cases["NaN"] = (times, v, sensor, "missing")
    v = values.copy(); v[100:400, j] = v[100, j]; cases["stuck"] = (times, v, sensor, "stuck")
    v = values.copy(); v[200, j] += 2 * pkg.safety["jump"][sensor]; cases["spike"] = (times, v, sensor, "jump")
    v = values.copy(); v[:, j] += np.linspace(0, 2 * span, n); cases["slow drift"] = (times, v, sensor, "out_of_range")
    keep = np.ones(n, bool); keep[300] = False
    cases["missing row"] = (times[keep], values[keep], "time", "time_gap")
    t = times.copy(); t[400:] += 3600; cases["time jump"] = (t, values, "time", "time_gap")
    rows = []
    for name, (tt, vv, who, why) in cases.items():
        hist = X.iloc[train]
        comp = pkg.compensator(history=hist[pkg.inputs].to_numpy(), history_times_s=hist.index.to_numpy())
        buf = io.StringIO()
        audit = Audit(buf, pkg, comp)
        written = []
        for a, b in zip(tt, vv):
            step = comp.update(a, b)
            audit.write(step, b)
            written.append(step.written[0])
        lines = [json.loads(x) for x in buf.getvalue().splitlines()]
        named = any({"sensor": who, "reason": why} in ln["reasons"] for ln in lines)
        first = next((i for i, ln in enumerate(lines) if {"sensor": who, "reason": why} in ln["reasons"]), None)
        where = f"row {first}" if named else "NOT named"
        rows.append([name, who, float(np.abs(np.diff(written)).max()), float(comp.max_step[0]),
                     float(np.abs(written).max()), float(comp.clamp[0]), f"{why} ({where})"])
    return rows


def dead_sensors(name, pkg, X, train, test, y):
    truth = y.iloc[test].to_numpy()[:, 0]
    _, steps = replay(pkg, X, train, test)
    full = rmse([s.written[0] for s in steps], truth)
    raw = rmse([s.raw[0] for s in steps], truth)
    limited = float(np.mean([s.status[0] != 0 for s in steps]) * 100)
    per = {}
    for sensor in pkg.fallbacks:
        values = X.iloc[test][pkg.inputs].to_numpy().copy()
        values[:, pkg.inputs.index(sensor)] = np.nan
        _, steps = replay(pkg, X, train, test, values=values)
        per[sensor] = rmse([s.written[0] for s in steps], truth)
    worst = max(per, key=per.get)
    med = float(np.median(list(per.values())))
    return [name, raw, full, limited, med, med / full, "met" if med <= 1.5 * full else "NOT met",
            f"{worst}: {per[worst]:.3g}", len(per)]


def probes(name, pkg, X, train, test, y):
    truth = y.iloc[test].to_numpy()[:, 0]
    times = X.index.to_numpy()[test].astype(float)
    _, steps = replay(pkg, X, train, test)
    base = rmse([s.written[0] for s in steps], truth)
    out = [name, base]
    for every_s in (1800.0, 7200.0):
        marks = np.arange(times[0] + every_s, times[-1], every_s)
        idx = np.searchsorted(times, marks)
        p = [(times[i], 0, truth[i]) for i in idx]
        _, steps = replay(pkg, X, train, test, probes=p)
        out.append(rmse([s.written[0] for s in steps], truth))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--soak", type=int, default=5, help="replays of FL_THERMAL in the soak (100: 1.1 M updates)")
    ap.add_argument("--models", nargs="+", default=list(MODELS))
    args = ap.parse_args(argv)
    os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
    import torch

    torch.set_num_threads(1)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, python "
          f"{platform.python_version()}; times are upper bounds on a shared machine")
    rec, train, test = setup()
    tmp = Path(tempfile.mkdtemp())
    built = {}
    for name in args.models:
        t0 = time.perf_counter()
        built[name] = build(name, rec, train, tmp / name)
        print(f"{name}: fitted and exported with {len(built[name][3].fallbacks)} fallbacks in "
              f"{time.perf_counter() - t0:.0f} s", flush=True)

    eq, speed = [], []
    for name, (model, X, y, pkg) in built.items():
        expected = model.predict(X.iloc[test], history=X.iloc[train])[:, 0]
        _, steps = replay(pkg, X, train, test, limits=False)
        tol = 1e-4 if name in NETWORKS else 1e-9
        diff = float(np.abs(np.array([s.written[0] for s in steps]) - expected).max())
        cli = cli_equality(tmp / name, rec, test, model, X, train) if name == "transfer_function" else "-"
        eq.append([name, diff, cli, tol, "met" if diff <= tol and (cli == "-" or cli <= tol) else "NOT met"])
        hist = X.iloc[train]
        comp = pkg.compensator(history=hist[pkg.inputs].to_numpy(), history_times_s=hist.index.to_numpy())
        stream = pkg.streamer(hist[pkg.inputs].to_numpy(), hist.index.to_numpy())
        vals, ts = X.iloc[test][pkg.inputs].to_numpy(), X.index.to_numpy()[test].astype(float)
        n = min(len(vals), 400 if name in NETWORKS else len(vals))
        guarded, bare = [], []
        for t, v in zip(ts[:n], vals[:n]):
            a = time.perf_counter(); comp.update(t, v); guarded.append(time.perf_counter() - a)
        for t, v in zip(ts[:n], vals[:n]):
            a = time.perf_counter(); stream.update(v, t); bare.append(time.perf_counter() - a)
        s, mb, heavy = import_cost(tmp / name)
        g = np.array(guarded) * 1e3
        speed.append([name, float(np.median(g)), float(np.percentile(g, 99)), float(np.median(bare) * 1e3),
                      "≤ 0.05" if name not in NETWORKS else "reported", s, mb, heavy])
    table("1. --no-limits replay equals predict with history (µm)",
          ["model", "max |diff| in-process", "max |diff| via `compensate` CSV", "tolerance", "status"], eq)
    table("2–3. Per update (ms) and runtime import",
          ["model", "guarded median", "guarded p99", "bare runtime median", "target", "import+load+1 update s",
           "import memory MB", "heavy modules"], speed)

    name = "transfer_function" if "transfer_function" in built else next(iter(built))
    model, X, y, pkg = built[name]
    vals, ts = X[pkg.inputs].to_numpy(), X.index.to_numpy().astype(float)  # the whole recording
    period = ts[-1] - ts[0] + (ts[1] - ts[0])
    comp = pkg.compensator()
    total = args.soak * len(vals)
    marks, t0 = {}, time.perf_counter()
    for r in range(args.soak):
        for t, v in zip(ts + r * period, vals):
            comp.update(t, v)
        if r + 1 == max(1, args.soak // 10):
            marks["10%"] = rss_mb()
    marks["end"] = rss_mb()
    table(f"4. Soak ({name}, audit off)", ["replays", "updates", "s", "RSS at 10 % MB", "RSS at end MB", "growth MB"],
          [[args.soak, total, time.perf_counter() - t0, marks["10%"], marks["end"], marks["end"] - marks["10%"]]])

    table(f"5. Fault injection ({name})", ["fault", "named", "max |Δ written| µm", "rate limit µm",
                                           "max |written| µm", "clamp µm", "audit reason"],
          faults(pkg, X, train, test, y))
    dead = [dead_sensors(n, built[n][3], built[n][1], train, test, built[n][2])
            for n in built if built[n][3].fallbacks]
    table("6. One sensor dead for the whole 5000 rpm block (RMSE µm; target: median ≤ 1.5 × full)",
          ["model", "model alone", "full (limits on)", "rows not ok %", "median over sensors", "ratio", "status",
           "worst sensor", "sensors"], dead)
    table("7. Probe updates (held-out RMSE µm)", ["model", "no probe", "every 30 min", "every 2 h"],
          [probes(n, built[n][3], built[n][1], train, test, built[n][2]) for n in built])
    return 0


if __name__ == "__main__":
    sys.exit(main())
