"""Physics benchmark: calibration you can trust, and physics models as a controller calls them.

Prints one table (``measured`` next to ``target``), every row reproducible (seeded, no wall-clock stop; times
are the only figures that move with the machine, and they are CPU time of this process, so a busy machine
inflates them less than wall-clock time):

* recovery — the two-node reference network simulated with known parameters, Pt100 offsets and noise for
  ``--seeds`` seeds, calibrated with its own (true) spec from a wrong start: share of parameters inside their
  95 % intervals (target ≥ 90 %);
* null case — a recording with nothing but speed-driven heat (inside the auto family), calibrated with
  ``--network auto``: worst RMSE / noise σ over channels (target ≤ 1.5); sensor offsets are fitted (projected);
* FL_THERMAL — the auto calibration of the whole recording (time, stop reason, evaluations, the strength of its
  prior and the block it was chosen on), and held-out RMSE
  per channel ch1–ch5 on ``experiment=fl_thermal_5000rpm_heldout`` (train t < 24.13 h, test 24.13–32.13 h, all
  16 temperatures) of ``lptn``, ``lptn_hybrid`` and ``mlr`` (targets: ch3 lptn_hybrid ≤ 3.5 µm, lptn ≤ 7 µm),
  and of the physics models from 5 jittered starts (``jitter_seed`` 1–5): ch3 range and max/min per channel
  (target ≤ 1.25);
* scaling — the null-case programme, 41 h at 15 s (~10 k samples) and at 1.5 s (~100 k; ``--full``: 287 h at
  1 s, ~1 M): calibration and
  mismatch-map time and displacement RMSE (target: time at most linear, RMSE at 1 M within 1.5 × of 10 k);
* streaming — every registered model fitted on the tiny recording: ms per ``streamer.update`` and the largest
  difference from ``predict(rows, history)`` (target ≤ 0.05 ms for linear, filter and physics models; 1e-4 µm).

Run::

    python benchmarks/bench_physics.py [--data /work/shared/data/fl_thermal] [--seeds 5] [--full]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from thermodrift.core import physics, registry
from thermodrift.core.metrics import rmse
from thermodrift.core.physics import calibration as cal
from thermodrift.core.physics import mismatch, scenarios, synthetic
from thermodrift.core.physics.scenarios import Block
from thermodrift.core.physics.synthetic import synthesize
from thermodrift.core.splits import TimeWindow

HERE = Path(__file__).resolve().parent
TWO_NODE = HERE.parent / "tests" / "data" / "two_node_network.yaml"
ROWS: list[tuple[str, str, str, str]] = []
STARTS = 5  # jittered starts (seeds 1..STARTS) of the physics models on FL_THERMAL


def row(case: str, detail: str, measured: str, target: str = "") -> None:
    ROWS.append((case, detail, measured, target))
    print(f"  {case}: {measured} ({detail})", flush=True)


def recovery(seeds: int) -> None:
    truth = physics.load_network(TWO_NODE)
    values = truth.parameters()
    start = truth.with_values({"edges.a-b.G_W_K": 4.5, "edges.a-ambient.G_W_K": 0.6, "edges.b-ambient.G_W_K": 6.0,
                               "sources.heat.viscous_W": 40.0})
    prog = scenarios.blocks([Block(0.25), Block(2, 3000), Block(1.5), Block(2, 6000), Block(1.5)], 60.0)
    inside = total = 0
    stops = set()
    for seed in range(seeds):
        result = cal.calibrate(synthesize(truth, prog, seed).recording, start,
                               free=["edges.*.G_W_K", "sources.heat.viscous_W"])
        stops.add(result.stop)
        for e in result.estimates:
            inside += e.low <= values[e.name] <= e.high
            total += 1
    row("recovery, true network", f"{total} parameters over {seeds} seeds, stop: {'/'.join(sorted(stops))}",
        f"{inside / total:.0%} inside 95 % CI", "≥ 90 %")


def speed_only(seed: int, dt_s: float = 15.0, repeats: int = 1):
    """Nothing but speed-driven heat (:func:`thermodrift.core.physics.synthetic.speed_only`)."""
    return synthetic.speed_only(seed, dt_s, repeats).recording


NOISE = {"T_front": 0.02, "T_rear": 0.02, "T_housing": 0.02, "dz": 0.1}


def null_case(seeds: int) -> None:
    worst = []
    for seed in range(seeds):
        result = cal.calibrate(speed_only(seed), hidden_nodes=1)
        worst.append(max(result.rmse[c] / s for c, s in NOISE.items()))
    row("null case, auto network", f"worst RMSE/σ over channels, {seeds} seeds; offsets fitted",
        f"{max(worst):.2f} (median {np.median(worst):.2f})", "≤ 1.5")


def fl_thermal(data: Path) -> None:
    recording = registry.create("dataset", "fl_thermal", **({"path": str(data)} if data else {}))
    start = time.process_time()
    result = cal.calibrate(recording)
    seconds = time.process_time() - start
    row("FL_THERMAL calibration, auto", f"{result.evaluations} simulations, stop: {result.stop}, "
        f"grid {result.fit_samples} × {result.grid_step_s:g} s", f"{seconds:.1f} CPU s", "tolerance, ≤ 60 s")
    worse = [w for w in result.warnings]
    prior = result.prior.validation
    row("  calibration prior", f"λ per row chosen on {prior['held_out_s'][0] / 3600:.1f}–"
        f"{prior['held_out_s'][1] / 3600:.1f} h, fit before", f"λ = {result.prior.strength:g}")
    for c in recording.columns("displacement"):
        row(f"  calibration {c}", "RMSE before -> after", f"{result.rmse_initial[c]:.2f} -> {result.rmse[c]:.2f} µm")
    row("  calibration warnings", "", str(len(worse)) + (f": {worse[0][:60]}…" if worse else ""))
    fold = TimeWindow(24.13, 24.13, 32.13).folds(recording)[0]
    targets = recording.columns("displacement")
    y = recording.data[targets]
    from thermodrift.core.study import model_inputs
    inputs = {name: model_inputs(recording, recording.columns("temperature"), registry.get("model", name).factory,
                                 targets) for name in ("lptn", "lptn_hybrid", "mlr")}

    def held_out(name: str, **params) -> tuple[np.ndarray, float]:
        """RMSE per channel (µm) on the held-out part and the CPU seconds of fit + predict."""
        X = inputs[name]
        start = time.process_time()
        model = registry.create("model", name, **params).fit(X.iloc[fold.train], y.iloc[fold.train])
        pred = model.predict(X.iloc[fold.test], history=X.iloc[fold.train])
        seconds = time.process_time() - start
        return rmse(y.iloc[fold.test].to_numpy(), pred, axis=0), seconds

    for name in ("lptn", "lptn_hybrid", "mlr"):
        err, seconds = held_out(name)
        target = {"lptn": "ch3 ≤ 7", "lptn_hybrid": "ch3 ≤ 3.5", "mlr": ""}[name]
        row(f"held out, {name}", f"ch1..ch5, fit+predict {seconds:.0f} CPU s",
            " ".join(f"{v:.2f}" for v in err) + " µm", target)
    for name in ("lptn", "lptn_hybrid"):
        errs = np.array([held_out(name, jitter_seed=seed)[0] for seed in range(1, STARTS + 1)])
        ratio = errs.max(axis=0) / errs.min(axis=0)
        row(f"  {name}, {STARTS} jittered starts", f"ch3 min–max µm; max/min ch1..ch5",
            f"{errs[:, 2].min():.2f}–{errs[:, 2].max():.2f} µm; " + " ".join(f"{v:.2f}" for v in ratio),
            "ch3 max/min ≤ 1.25")


def scaling(cases: list[tuple[float, int]]) -> None:
    """Each case (dt s, repeats of the 20.5 h programme): calibrate and map times and the dz RMSE."""
    base = None
    for dt, repeats in cases:
        rec = speed_only(0, dt_s=dt, repeats=repeats)
        start = time.process_time()
        result = cal.calibrate(rec, hidden_nodes=1, intervals=False)
        cal_s = time.process_time() - start
        start = time.process_time()
        mismatch.mismatch_map(result)
        mm_s = time.process_time() - start
        base = base or (len(rec), cal_s, mm_s, result.rmse["dz"])
        row(f"scaling {len(rec):,} samples", f"dt {dt:g} s, {rec.duration_s / 3600:.0f} h, grid {result.fit_samples}"
            f" × {result.grid_step_s:g} s, stop {result.stop}",
            f"calibrate {cal_s:.1f} CPU s, map {mm_s:.2f} CPU s, dz RMSE {result.rmse['dz']:.3f} µm "
            f"(×{result.rmse['dz'] / base[3]:.2f} of the first)", "linear time; RMSE ≤ 1.5×")


def streaming() -> None:
    from thermodrift.core.study import model_inputs
    from thermodrift.testing.data import tiny_frames, tiny_recording

    X, y = tiny_frames()
    for name in registry.names("model"):
        factory = registry.get("model", name).factory
        params = factory.get_test_params()[0]
        model = registry.create("model", name, **params)
        Xm = model_inputs(tiny_recording(), list(X.columns), factory, list(y.columns)).loc[X.index]
        model.fit(Xm, y)
        cut = len(Xm) // 2
        rows = Xm.iloc[cut:cut + 200]
        batch = model.predict(rows, history=Xm.iloc[:cut])
        streamer = model.streamer(Xm.iloc[:cut])
        items = [rows.iloc[i] for i in range(len(rows))]
        start = time.process_time()
        out = np.array([streamer.update(r) for r in items])
        ms = (time.process_time() - start) / len(rows) * 1e3
        row(f"streaming {name}", f"history_length {model.history_length}",
            f"{ms:.3f} CPU ms/update, max diff {np.abs(out - batch).max():.1e} µm", "≤ 0.05 ms; ≤ 1e-4 µm")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None,
                        help="folder of the FL_THERMAL workbook (default: the dataset's own lookup)")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--full", action="store_true", help="add the 1 M-sample scaling case")
    args = parser.parse_args(argv)
    fl_thermal(args.data)
    recovery(args.seeds)
    null_case(args.seeds)
    streaming()
    scaling([(15.0, 2), (1.5, 2)] + ([(1.0, 14)] if args.full else []))
    w = [max(len(r[i]) for r in ROWS + [("case", "detail", "measured", "target")]) for i in range(4)]
    print()
    print("| " + " | ".join(h.ljust(n) for h, n in zip(("case", "detail", "measured", "target"), w)) + " |")
    print("|" + "|".join("-" * (n + 2) for n in w) + "|")
    for r in ROWS:
        print("| " + " | ".join(v.ljust(n) for v, n in zip(r, w)) + " |")


if __name__ == "__main__":
    main()
