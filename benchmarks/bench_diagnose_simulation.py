"""Missing-physics finder against the user's own simulation (``diagnose --simulation``): concealed-effect cases
from the independent generators, each with its user's simulation, and semi-synthetic FL_THERMAL.

Every case, nulls included, comes with the user's simulation (:mod:`independent.user_sim`): the same drawn
machine without the concealed mechanism, every physical parameter off by a lognormal factor of relative size
``--errors`` (default 0.2), every second case also with structural error (a coarser discretisation of the fd
machine, bodies of the lumped one merged further), driven by the recorded inputs. Every driver (ambient with
daily and HVAC cycles, a cycling chiller, cutting, axis motion) is active in every case. The finder is told
which recorded inputs drove the simulation (the user knows their model: the hall air, and the chiller inlet
when the simulation has the motor jacket), or with ``--detect-inputs`` reads them from its traces.

Scores: top-1 over the mechanism cases (and over the ones whose mechanism the report lists as tested), the
share of cases with a wrong mechanism named, null cases with a finding, the median held-out drift cut over
correct finds (on the drift channel where the planted effect is largest, final block), the report's status
of the concealed mechanism on misses (tested / nested / untestable), and run time per case (noisy: the machine
is shared).

Semi-synthetic FL_THERMAL (``--fl``): the user's simulation is calibrated on the plain recording, either a
regression of each drift channel on the measured temperatures and their lags (``--fl-kind regression``, the
default: it reproduces the plain drift to 0.4–0.7 µm RMS, as a calibrated model of the machine does) or the
``auto`` network run on the recorded inputs (``--fl-kind auto``: 3–11 µm RMS, a simulation missing most of the
machine); the three plantings of :mod:`independent.fl_semi` (and their controls) are diagnosed against it. A
planted effect counts as named when it is found on the planted recording and not on its control.

Seeds: development cases are seeds < 1000 (:func:`independent.case_list`); ``--sealed`` runs the sealed range
from ``--sealed-base`` (default 23000, a fresh one; run once, at the end).

Run::

    python benchmarks/bench_diagnose_simulation.py                      # both generators, 11 + 4 nulls each (~5 min)
    python benchmarks/bench_diagnose_simulation.py --full --results dev.jsonl        # 33 + 20 per generator
    python benchmarks/bench_diagnose_simulation.py --per 2 --nulls 12 --both-settings  # the development set (136)
    python benchmarks/bench_diagnose_simulation.py --full --sealed --results sealed.jsonl
    python benchmarks/bench_diagnose_simulation.py --fl [--seed N]      # semi-synthetic FL_THERMAL only
    python benchmarks/bench_diagnose_simulation.py --timing             # one 30 h recording at 15 s
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from thermodrift.core.physics.diagnose import report as dx_report
from thermodrift.core.physics.diagnose.against_simulation import diagnose_simulation
from thermodrift.core.recording import load_recording

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import independent  # noqa: E402 - the independent generator package next to this script
from independent.user_sim import make_sim_case  # noqa: E402

DEFAULT_DATA = HERE.parent.parent / "shared" / "data" / "fl_thermal"
SEALED_BASE = 23000  # fresh; 11000, 14000, 17000, 19000, 20000, 21000 and 22000 are spent


def run_case(generator: str, seed: int, hidden: str | None, error: float, structural: bool, step_s: float,
             detect: bool, folder: Path) -> dict:
    gen, sim = make_sim_case(seed, hidden, generator, error, structural, step_s)
    rec = load_recording(*gen.write(folder))
    start = time.perf_counter()
    d = diagnose_simulation(rec, sim, simulated_inputs=None if detect else gen.info["simulated_inputs"])
    seconds = time.perf_counter() - start
    doc = dx_report.to_json(d)
    found = [f["mechanism"] for f in d.findings]
    ch = gen.drift_channel
    before, after = doc["baseline"]["heldout_rmse_um"][ch], doc["augmented"]["heldout_rmse_um"][ch]
    status = {m["mechanism"]: m for m in d.adequacy["mechanisms"]}
    mine = status.get(hidden or "", {})
    return {"case": f"{generator}_{hidden or 'none'}_{seed}_e{error:g}_{'s' if structural else 'x'}_{step_s:g}s",
            "generator": generator, "seed": seed, "hidden": hidden or "none", "error": error,
            "structural": structural, "top1": found[0] if found else "none", "found": found, "seconds": seconds,
            "samples": len(rec), "cut": 1 - after / before if before > 0 else 0.0, "cut_channel": ch,
            "share": gen.share, "status": mine.get("status", ""), "reason": mine.get("reason", ""),
            "simulated_inputs": d.adequacy["simulated_inputs"],
            "tested": [{k: m[k] for k in ("mechanism", "share", "gain", "folds_improved", "fold_share",
                                                "size_noise_units", "passed", "reason")}
                       for m in d.adequacy["mechanisms"] if m["status"] == "tested"]}


FL_LAGS_S = (1800.0, 7200.0)  # the regression simulation's first-order lags of each temperature (s)


def regression_simulation(rec):
    """The drift channels of a recording as a least-squares model of its own measured temperatures (each as
    measured and through :data:`FL_LAGS_S`, tiny ridge), fitted on every row: a simulation calibrated to the
    plain machine (FL_THERMAL: 0.43–0.74 µm RMS against 2.7–11.4 µm for the ``auto`` network)."""
    import pandas as pd

    from thermodrift.core.physics.sensors import first_order_lag

    temps = rec.data[[c for c in rec.channels if rec.channels[c].role == "temperature"]].to_numpy(float)
    cols = [np.ones(len(temps))]
    for x in (temps - temps[0]).T:
        cols += [x] + [first_order_lag(x, rec.time_s, tau) for tau in FL_LAGS_S]
    X = np.column_stack(cols)
    X /= np.abs(X).max(axis=0)
    gram = X.T @ X
    gram += 1e-6 * np.trace(gram) / len(gram) * np.eye(len(gram))
    sim = pd.DataFrame(index=pd.Index(rec.time_s, name="time_s"))
    for c in (c for c in rec.channels if rec.channels[c].role == "displacement"):
        sim[c] = X @ np.linalg.solve(gram, X.T @ rec.data[c].to_numpy(float))
    return sim


def fl_cases(data: Path, seed: int, keep: Path | None = None, kind: str = "regression") -> list[dict]:
    """Semi-synthetic FL_THERMAL against a simulation of the plain recording: ``regression``
    (:func:`regression_simulation`) or the ``auto`` network calibrated on it (see the module docstring).
    ``keep``: a CSV the ``auto`` simulation is written to, and read from when it exists."""
    import pandas as pd
    from independent import fl_semi

    from thermodrift.core.physics.calibration import calibrate
    from thermodrift.core.physics.diagnose.simulation_table import drive
    from thermodrift.core.recording import Channel, Recording

    manifest = HERE.parent / "plugins" / "datasets" / "fl_thermal.yaml"
    rec = load_recording(data / "data.xlsx", manifest)
    start = time.perf_counter()
    if kind == "regression":
        sim = regression_simulation(rec)
    elif keep is not None and keep.is_file():
        sim = pd.read_csv(keep, index_col="time_s")
    else:
        cal = calibrate(rec, None, intervals=False, prior_strength=0.0, seed=seed)
        sim = drive(cal.network, rec)
        if keep is not None:
            sim.to_csv(keep)
        print(f"FL_THERMAL: auto network calibrated on the plain recording in {time.perf_counter() - start:.0f} s",
              file=sys.stderr, flush=True)
    specs = fl_semi.case_specs(rec, seed)
    rows = []
    for label, added, drift, mechanism, control in specs:
        frame, channels = rec.data.copy(), dict(rec.channels)
        for col, (role, unit, values) in added.items():
            frame[col] = values
            channels[col] = Channel(col, role, unit, {})
        for col, values in drift.items():
            frame[col] = frame[col] + values
        t0 = time.perf_counter()
        d = diagnose_simulation(Recording(frame, channels, rec.source + label[len("fl_thermal"):]), sim,
                                simulated_inputs=[])
        rows.append({"case": label, "found": [f["mechanism"] for f in d.findings], "planted": mechanism,
                     "control": control, "seconds": time.perf_counter() - t0})
        print(f"{label:<60} {', '.join(rows[-1]['found']) or 'none':<30} {rows[-1]['seconds']:5.1f} s",
              file=sys.stderr, flush=True)
    return rows


def report_fl(rows: list[dict], kind: str = "regression") -> str:
    by = {r["case"]: r for r in rows}
    sim = {"regression": "a regression on its own temperatures", "auto": "the auto network"}[kind]
    out = [f"## Semi-synthetic FL_THERMAL (simulation: {sim}, calibrated on the plain recording)", "",
           "| case | found | control found | named |", "|---|---|---|---|"]
    named = 0
    for r in rows:
        if not r["planted"]:
            out.append(f"| {r['case']} | {', '.join(r['found']) or 'none'} | | |")
            continue
        ctrl = by.get(r["control"], {}).get("found", [])
        ok = bool(r["found"]) and r["found"][0] == r["planted"] and r["planted"] not in ctrl
        named += ok
        out.append(f"| {r['case']} | {', '.join(r['found']) or 'none'} | {', '.join(ctrl) or 'none'} | "
                   f"{'yes' if ok else 'no'} |")
    planted = sum(1 for r in rows if r["planted"])
    out += ["", f"Planted effects named: {named} of {planted} (target ≥ 2 of 3).", ""]
    return "\n".join(out)


def report(rows: list[dict]) -> str:
    hidden = [r for r in rows if r["hidden"] != "none"]
    nulls = [r for r in rows if r["hidden"] == "none"]
    correct = [r for r in hidden if r["top1"] == r["hidden"]]
    wrong = [r for r in rows if r["top1"] not in ("none", r["hidden"])]
    testable = [r for r in hidden if r["status"] == "tested"]
    cuts = [r["cut"] for r in correct]
    secs = [r["seconds"] for r in rows]
    out = ["## Summary", "", "| metric | value | target |", "|---|---:|---:|",
           f"| top-1, mechanism cases | {len(correct)}/{len(hidden)} ({len(correct) / max(len(hidden), 1):.0%}) "
           f"| ≥ 90 % |",
           f"| top-1, cases whose mechanism is tested | {sum(r['top1'] == r['hidden'] for r in testable)}/"
           f"{len(testable)} | |",
           f"| wrong mechanism named, all cases | {len(wrong)}/{len(rows)} ({len(wrong) / max(len(rows), 1):.1%}) "
           f"| ≤ 2 % |",
           f"| null cases with a finding | {sum(r['top1'] != 'none' for r in nulls)}/{len(nulls)} | 0 |",
           f"| median held-out drift cut, correct finds | "
           f"{statistics.median(cuts) if cuts else float('nan'):.0%} | ≥ 50 % |",
           f"| median / max seconds per case (loaded machine) | {statistics.median(secs) if secs else 0:.1f} / "
           f"{max(secs) if secs else 0:.1f} | ≤ 30 s at 15 s |", ""]
    out += ["## Per mechanism (correct / cases; what the report says on the misses)", "",
            "| hidden | correct | found instead | status of the hidden mechanism on misses |", "|---|---:|---|---|"]
    for h in sorted({r["hidden"] for r in rows}):
        rs = [r for r in rows if r["hidden"] == h]
        ok = sum(r["top1"] == h for r in rs)
        instead = Counter(r["top1"] for r in rs if r["top1"] != h)
        status = Counter(r["status"] or "-" for r in rs if r["top1"] != h)
        out.append(f"| {h} | {ok}/{len(rs)} | {', '.join(f'{k} {v}' for k, v in instead.items())} | "
                   f"{', '.join(f'{k} {v}' for k, v in status.items())} |")
    out += ["", "## By setting (top-1 on mechanism cases; null cases with a finding)", "",
            "| generator | error | structural | top-1 | null findings |", "|---|---:|---|---:|---:|"]
    for key in sorted({(r["generator"], r["error"], r["structural"]) for r in rows}):
        rs = [r for r in rows if (r["generator"], r["error"], r["structural"]) == key]
        hs, ns = [r for r in rs if r["hidden"] != "none"], [r for r in rs if r["hidden"] == "none"]
        out.append(f"| {key[0]} | {key[1]:g} | {'yes' if key[2] else 'no'} | "
                   f"{sum(r['top1'] == r['hidden'] for r in hs)}/{len(hs)} | "
                   f"{sum(r['top1'] != 'none' for r in ns)}/{len(ns)} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--generator", choices=("fd", "lumped", "both"), default="both")
    ap.add_argument("--full", action="store_true", help="3 cases per mechanism and 20 nulls per generator")
    ap.add_argument("--per", type=int, metavar="N", help="cases per mechanism and generator (overrides --full)")
    ap.add_argument("--nulls", type=int, metavar="N", help="null cases per generator (overrides --full)")
    ap.add_argument("--sealed", action="store_true", help="the sealed range (run once, at the end)")
    ap.add_argument("--sealed-base", type=int, default=SEALED_BASE, metavar="SEED")
    ap.add_argument("--errors", type=float, nargs="+", default=[0.2], help="parameter error sizes (default 0.2)")
    ap.add_argument("--both-settings", action="store_true",
                    help="every case with and without structural error (default: every second case structural)")
    ap.add_argument("--detect-inputs", action="store_true",
                    help="read the inputs that drove the simulation from its traces instead of being told")
    ap.add_argument("--step-s", type=float, default=120.0, help="logging interval (default 120 s)")
    ap.add_argument("--timing", action="store_true", help="only one 30 h recording at 15 s per generator")
    ap.add_argument("--only", nargs="+", metavar="MECHANISM", help="only these hidden mechanisms ('none': nulls)")
    ap.add_argument("--part", metavar="K/N", help="only every N-th case from the K-th (1-based)")
    ap.add_argument("--results", type=Path, help="JSON lines of finished cases; cases already in it are skipped")
    ap.add_argument("--pool", nargs="+", type=Path, help="run nothing: report over these --results files")
    ap.add_argument("--fl", action="store_true", help="only the semi-synthetic FL_THERMAL cases")
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder with FL_THERMAL data.xlsx")
    ap.add_argument("--fl-simulation", type=Path, metavar="CSV",
                    help="with --fl: keep the calibrated simulation in this CSV (read it when it exists)")
    ap.add_argument("--fl-kind", choices=("regression", "auto"), default="regression",
                    help="with --fl: the user's simulation of the plain recording (default: regression)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    if args.fl:
        if not (args.data / "data.xlsx").is_file():
            print(f"bench: {args.data / 'data.xlsx'} not found; pass --data FOLDER", file=sys.stderr)
            return 2
        print(report_fl(fl_cases(args.data, args.seed, args.fl_simulation, args.fl_kind), args.fl_kind))
        return 0
    if args.pool:
        rows = [json.loads(line) for f in args.pool for line in f.read_text(encoding="utf-8").splitlines() if line]
        print(report(list({r["case"]: r for r in rows}.values())))
        return 0
    done = {}
    if args.results and args.results.is_file():
        done = {r["case"]: r for r in (json.loads(x) for x in args.results.read_text(encoding="utf-8").splitlines()
                                       if x.strip())}
    per, nulls = (3, 20) if args.full else (1, 4)
    per, nulls = args.per or per, args.nulls if args.nulls is not None else nulls
    gens = ("fd", "lumped") if args.generator == "both" else (args.generator,)
    specs = []
    cases = independent.case_list(args.sealed, per, nulls, args.sealed_base if args.sealed else 0)
    if args.timing:
        cases = [(cases[0][0] + 900, "coolant_coupling", False)]
    for i, (seed, hidden, _) in enumerate(cases):
        for g in gens:
            for error in args.errors:
                for structural in ((False, True) if args.both_settings else (i % 2 == 1,)):
                    specs.append((g, seed, hidden, error, structural, 15.0 if args.timing else args.step_s))
    # generators, mechanism and null cases interleaved: a run cut short (or one --part) holds a balanced share
    hid, nul = [s for s in specs if s[2]], [s for s in specs if not s[2]]
    specs = [s for _, _, s in sorted([(i / len(hid), 0, s) for i, s in enumerate(hid)]
                                     + [((i + 0.5) / len(nul), 1, s) for i, s in enumerate(nul)],
                                     key=lambda x: (x[0], x[1]))]
    if args.only:
        specs = [s for s in specs if (s[2] or "none") in args.only]
    if args.part:
        k, n = (int(v) for v in args.part.split("/"))
        specs = specs[k - 1::n]
    rows, start = [], time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bench-dx-sim-") as tmp:
        for g, seed, hidden, error, structural, step in specs:
            name = f"{g}_{hidden or 'none'}_{seed}_e{error:g}_{'s' if structural else 'x'}_{step:g}s"
            if name in done:
                rows.append(done[name])
                continue
            r = run_case(g, seed, hidden, error, structural, step, args.detect_inputs, Path(tmp))
            rows.append(r)
            if args.results:
                with args.results.open("a", encoding="utf-8") as fh:
                    fh.write(json.dumps(r) + "\n")
            print(f"{r['case']:<48} top-1 {r['top1']:<28} cut {r['cut']:5.0%} {r['seconds']:5.1f} s",
                  file=sys.stderr, flush=True)
    half = f"sealed range from {args.sealed_base}" if args.sealed else "development seeds"
    print(f"# diagnose --simulation benchmark ({', '.join(gens)}; {half}; parameter error "
          f"{', '.join(f'{e:g}' for e in args.errors)}; half structural; inputs "
          f"{'read from the traces' if args.detect_inputs else 'given'}; {time.perf_counter() - start:.0f} s)\n")
    print(report(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
