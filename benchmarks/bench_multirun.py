"""Multi-run benchmark: ``thermodrift automl`` on machines recorded day by day, whole days held out, against the
best single family chosen with hindsight and FLAML.

Recordings: a machine of an independent generator (``benchmarks/independent``, no code shared with the library;
``fd`` the finite-volume machining centre, ``lumped`` the lumped network of another topology per seed) recorded on
``--days`` working days (default 6). Each day is a cold start: the machine at rest with that day's hall air (and
floor), its own hall (mean 18–24 °C, quiet or lively with HVAC cycling), its own speed programme of 7–10 hours
from a morning start (levels of the machine's one top speed), the temperature sensors re-clamped (each day's offset ±0.15 K beside the sensor's own
±0.3 K), the drift probe zeroed again (±1 µm beside its own ±20 µm). The drift is measured against a reference at
20 °C, so a warmer hall shows as a longer machine. Logged every 60 s: spindle speed, three to five surface
temperatures, the hall air and the z drift (x too on some machines), written as one table with a ``day`` column
(manifest ``run: day``) and read back through the public file format: each day one run.

Tasks per recording: the last day held out (``last``), and the day with the warmest hall (mean air) among the others
(``hot``); split ``run_holdout``, training on every other day. Per task:

* automl at its default budget (120 fits; every built-in family that can run without a heating channel, an
  installed outside plugin left out; ``automl.n_jobs`` the cores): held-out RMSE (µm, mean over
  the drift channels), wall and CPU time, the choice and its extrapolation warning;
* the hindsight best family: every family untuned on all sensors (networks at a ninth of their epochs), as
  ``bench_automl.py`` scores it, each on the held-out day; ``--hindsight-trials N`` adds N TPE trials per family;
* FLAML (``pip install -e ".[compare]"``), given automl's wall time on one core, per target, on the raw inputs and
  on automl's default feature stage, its validation the last 25 % of the training rows (``bench_automl.py``'s
  :func:`flaml_scores`); left out, and said so, when not installed.

Prints a table per task and the counts against the targets: automl within 1.2× of the hindsight best on at least
80 % of the tasks and below FLAML on every one. Seeds: development seeds below 1000 (``--seeds``, default the
first of each generator); the sealed range from 21000 (``--sealed``), run once at the end. Results are cached per
task in ``--cache`` (JSON), so a run resumes. Wall times depend on the machine's load.

Run::

    python benchmarks/bench_multirun.py                       # two tasks: fd seed 0 last day, lumped seed 1 hot day
    python benchmarks/bench_multirun.py --seeds 0 1 2 3 --kinds last hot   # the development set (8 tasks)
    python benchmarks/bench_multirun.py --sealed              # the sealed set (8 tasks), once
    python benchmarks/bench_multirun.py --seeds 0 1 2 3 --no-speed   # the same machines logged without speed
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from thermodrift.core import registry
from thermodrift.core.study import JobSpec

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_automl  # noqa: E402 - automl, the hindsight families and FLAML scored as bench_automl.py does
from independent import fd_model  # noqa: E402 - the independent generators (no code shared with the library)
from independent.programme import Programme, lagged, programme, room, sample  # noqa: E402

DAY_S = 86400.0
REF_DEGC = 20.0  # the drift's reference temperature: the machine at 20 °C throughout measures 0 µm (before offsets)
STEP_S, EVERY = 15.0, 4  # integration step (s) and samples per logged row (a row every 60 s)
SITES = bench_automl.independent.SENSOR_SITES  # sensor: (node, probability it is fitted)
GENERATORS = ("fd", "lumped")
SEALED_FROM = 21000
DEFAULT_TASKS = [("fd", 0, "last"), ("lumped", 1, "hot")]
WITHIN, SHARE = 1.2, 0.8  # Done means: within 1.2x of the hindsight best on >= 80 % of tasks, below FLAML on all


def generator_of(seed: int) -> str:
    """Even seeds draw the ``fd`` machine, odd seeds the ``lumped`` one."""
    return GENERATORS[seed % 2]


def multiday(generator: str, seed: int, days: int) -> tuple[pd.DataFrame, dict, dict]:
    """A machine of ``generator`` recorded on ``days`` days (see the module docstring): the table (``time_s``,
    ``day`` and the channels), its manifest, and per day the hall's mean air (°C)."""
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence([seed, 41]).spawn(2 + days)]
    r_machine, r_sensor, r_days = streams[0], streams[1], streams[2:]
    machine = fd_model.build(r_machine, lumped=generator == "lumped")
    n_top = float(r_machine.choice([6000.0, 8000.0, 10000.0, 12000.0]))  # the spindle's top speed (rpm)
    site = {**machine.info, "column_head": machine.info["j_head"],
            "bed": machine.seg("bed").idx[len(machine.info["table"]) // 2]}
    chosen = [s for s, (_, p) in SITES.items() if r_sensor.random() < p]
    chosen += [s for s in SITES if s not in chosen][:max(0, 3 - len(chosen))]
    sensors = {s: (int(site[SITES[s][0]]), r_sensor.uniform(0.01, 0.05), r_sensor.uniform(5.0, 40.0),
                   r_sensor.uniform(-0.3, 0.3), r_sensor.uniform(0.01, 0.03)) for s in SITES if s in chosen}
    axes = ["z", "x"] if r_sensor.random() < 0.4 else ["z"]
    amb_tau, amb_offset = r_sensor.uniform(60.0, 240.0), r_sensor.uniform(-0.2, 0.2)
    probe = {c: r_sensor.uniform(-20.0, 20.0) for c in axes}
    probe_noise = r_sensor.uniform(0.05, 0.15)
    frames, hall = [], {}
    for d, rng in enumerate(r_days):
        label = f"day{d + 1:02d}"
        start_h = rng.uniform(5.5, 8.0)
        prog = programme(rng, rng.uniform(7.0, 10.0), STEP_S, False, False)
        prog = Programme(prog.t, prog.h, prog.speed * n_top / prog.n_max, prog.cutting_W, prog.feed, n_top)
        air = room(rng, prog.t, bool(rng.random() < 0.5), start_h)
        res = fd_model.simulate(machine, prog, air, float(air.mean() - rng.uniform(0.5, 2.0)), None,
                                fd_model.Effect())
        n = len(prog.t[::EVERY])
        cols = {"time_s": d * DAY_S + start_h * 3600.0 + prog.t[::EVERY], "day": [label] * n,
                "spindle_rpm": sample(prog.speed, EVERY)}
        for s, (node, drop, tau, offset, noise) in sensors.items():
            surface = res.T[:, node] - drop * (res.T[:, node] - air)
            cols[s] = np.round(sample(lagged(surface, tau, STEP_S), EVERY) + offset + rng.uniform(-0.15, 0.15)
                               + rng.normal(0.0, noise, n), 2)
        cols["ambient_degC"] = np.round(sample(lagged(air, amb_tau, STEP_S), EVERY) + amb_offset
                                        + rng.normal(0.0, 0.02, n), 2)
        for c in axes:  # against the 20 °C reference, so the day's hall level shows; the probe zeroed each morning
            drift = (res.T - REF_DEGC) @ machine.drift_w[c]
            cols[f"disp_{c}_um"] = np.round(sample(drift, EVERY) + probe[c] + rng.uniform(-1.0, 1.0)
                                            + rng.normal(0.0, probe_noise, n), 2)
        frames.append(pd.DataFrame(cols))
        hall[label] = float(air.mean())
    channels = {"spindle_rpm": {"role": "speed", "unit": "rpm"},
                **{s: {"role": "temperature", "unit": "degC", "location": SITES[s][0]} for s in sensors},
                "ambient_degC": {"role": "ambient", "unit": "degC"},
                **{f"disp_{c}_um": {"role": "displacement", "unit": "um", "axis": c} for c in axes}}
    manifest = {"description": f"independent {generator} generator, seed {seed}, {days} days, each a cold start",
                "time": "time_s", "run": "day", "channels": channels}
    return pd.concat(frames, ignore_index=True), manifest, hall


def held_day(hall: dict[str, float], kind: str) -> str:
    """The day a task holds out: ``last`` the last day, ``hot`` the warmest hall among the others."""
    days = list(hall)
    if kind == "last":
        return days[-1]
    return max(days[:-1], key=hall.get)


def task_spec(generator: str, seed: int, kind: str, days: int, folder: Path,
              speed: bool = True) -> tuple[JobSpec, dict]:
    """The recording written to ``folder`` (table + manifest) and the automl job spec holding out the task's day;
    ``speed`` False: the manifest leaves the spindle speed out (a machine logged without it)."""
    table, manifest, hall = multiday(generator, seed, days)
    if not speed:
        manifest["channels"].pop("spindle_rpm")
    folder.mkdir(parents=True, exist_ok=True)
    stem = folder / f"{generator}_{seed}_d{days}{'' if speed else '_nospeed'}"
    table.to_csv(stem.with_suffix(".csv"), index=False, float_format="%.4f")
    stem.with_suffix(".yaml").write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")
    day = held_day(hall, kind)
    spec = JobSpec(dataset="recording_file", dataset_params={"table": str(stem.with_suffix(".csv")),
                                                             "manifest": str(stem.with_suffix(".yaml"))},
                   model="mlr", split="run_holdout", split_params={"test_runs": [day]}, targets=None, seed=seed,
                   storage=None, progress=False)
    return spec, {"day": day, "hall_degC": hall}


def run_task(generator: str, seed: int, kind: str, args) -> dict:
    """automl, the hindsight families and FLAML on one task (see the module docstring)."""
    name = f"{generator}{seed}_{kind}{'' if args.speed else '_nospeed'}"
    spec, info = task_spec(generator, seed, kind, args.days, args.cache / "recordings", args.speed)
    recording = registry.create("dataset", spec.dataset, **spec.dataset_params)
    print(f"{name}: {len(recording.data)} rows, {len(info['hall_degC'])} days, holding out {info['day']} (hall "
          f"{info['hall_degC'][info['day']]:.1f} °C; the others "
          f"{min(v for k, v in info['hall_degC'].items() if k != info['day']):.1f} to "
          f"{max(v for k, v in info['hall_degC'].items() if k != info['day']):.1f} °C)", flush=True)
    from thermodrift.core.automl import job as automl_job, space
    from thermodrift.core.automl.search import Settings

    # the families a user's install has (an installed outside plugin left out) that can run on this recording
    roles = {ch.role for ch in recording.channels.values()}
    families = [f.name for f in space.families(roles=roles) if registry.get("model", f.name).origin == "thermodrift"]

    started, cpu = time.perf_counter(), time.process_time()
    before = _children_cpu()
    result = automl_job.run(spec, Settings(families=families), recording=recording)
    result.leaderboard.to_csv(args.cache / f"{name}-d{args.days}-leaderboard.csv", index=False)
    automl = {"wall_s": time.perf_counter() - started, "cpu_s": time.process_time() - cpu + _children_cpu() - before,
              **bench_automl.held_out(result.job), "chosen": result.describe()[:200],
              "extrapolates": result.extrapolates()}
    print(f"  automl: {automl['rmse']:.3f} µm in {automl['wall_s']:.0f} s ({automl['cpu_s']:.0f} s of CPU): "
          f"{automl['chosen']}", flush=True)
    best = bench_automl.hindsight(spec, recording, families, args.hindsight_trials)
    flaml = bench_automl.flaml_scores(spec, recording, automl["wall_s"])
    return {"task": name, "generator": generator, "seed": seed, "kind": kind, **info, "rows": len(recording.data),
            "automl": automl, "hindsight": best, "flaml": flaml}


def _children_cpu() -> float:
    import os

    t = os.times()
    return t.children_user + t.children_system


def task_table(r: dict) -> str:
    """One task: automl, MLR and persistence, every family, FLAML; held-out RMSE (µm) and the ratio to automl's."""
    a = r["automl"]
    rows = [("automl", a["rmse"]), ("MLR baseline (every temperature)", a["mlr"]),
            ("persistence baseline", a["persistence"])]
    rows += sorted(((f"family {k}", v) for k, v in r["hindsight"]["all"].items()), key=lambda kv: _key(kv[1]))
    rows += [(f"FLAML {k}", v) for k, v in (r["flaml"] or {}).items()]
    lines = [f"{r['task']} (held out {r['day']}, {r['rows']} rows):", f"  {'':<38}{'RMSE µm':>9}{'/ automl':>10}"]
    lines += [f"  {who:<38}{v:>9.3f}{v / a['rmse']:>10.2f}" for who, v in rows]
    lines.append(f"  chosen: {a['chosen']}")
    if a["extrapolates"]:
        lines.append(f"  {a['extrapolates']}")
    return "\n".join(lines)


def _key(v: float) -> float:
    return v if np.isfinite(v) else np.inf


def summary(results: list[dict]) -> str:
    """The tasks side by side and the counts against the targets."""
    lines = [f"{'task':<16}{'automl µm':>10}{'hindsight best':>22}{'µm':>8}{'ratio':>7}{'FLAML best µm':>15}"
             f"{'ratio':>7}{'wall s':>8}"]
    within = below = with_flaml = 0
    for r in results:
        a, h, fl = r["automl"], r["hindsight"], r["flaml"]
        ratio = a["rmse"] / h["rmse"]
        within += ratio <= WITHIN
        fbest = min(fl.values()) if fl else float("nan")
        with_flaml += bool(fl)
        below += bool(fl) and a["rmse"] < fbest
        lines.append(f"{r['task']:<16}{a['rmse']:>10.3f}{h['best']:>22}{h['rmse']:>8.3f}{ratio:>7.2f}"
                     f"{fbest:>15.3f}{a['rmse'] / fbest:>7.2f}{a['wall_s']:>8.0f}")
    n = len(results)
    lines.append(f"automl within {WITHIN}x of the hindsight best on {within} of {n} tasks ({within / n:.0%}; target "
                 f">= {SHARE:.0%}: {'met' if within >= SHARE * n else 'not met'}); below FLAML on {below} of "
                 f"{with_flaml} tasks with FLAML (target: every one: "
                 f"{'met' if with_flaml == n and below == n else 'not met'})")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="*", help="development seeds (< 1000; even: fd, odd: lumped)")
    parser.add_argument("--kinds", nargs="*", default=["last", "hot"], choices=["last", "hot"])
    parser.add_argument("--sealed", action="store_true", help=f"the sealed set: seeds {SEALED_FROM} to "
                        f"{SEALED_FROM + 3}, both kinds (run once, at the end)")
    parser.add_argument("--days", type=int, default=6, help="days per recording")
    parser.add_argument("--hindsight-trials", type=int, default=0, help="TPE trials per family for the hindsight")
    parser.add_argument("--cache", type=Path, default=Path(".bench_cache/multirun"), help="per-task results (JSON)")
    parser.add_argument("--json", type=Path, help="write every task's result here")
    parser.add_argument("--no-speed", dest="speed", action="store_false",
                        help="leave the spindle speed out of the manifest (a machine logged without it)")
    args = parser.parse_args()
    if args.sealed:
        tasks = [(generator_of(s), s, k) for s in range(SEALED_FROM, SEALED_FROM + 4) for k in ("last", "hot")]
    elif args.seeds:
        if any(s >= 1000 for s in args.seeds):
            raise SystemExit("bench_multirun: development seeds are below 1000; the sealed set runs with --sealed")
        tasks = [(generator_of(s), s, k) for s in args.seeds for k in args.kinds]
    else:
        tasks = DEFAULT_TASKS
    args.cache.mkdir(parents=True, exist_ok=True)
    results = []
    for generator, seed, kind in tasks:
        path = args.cache / (f"{generator}{seed}_{kind}{'' if args.speed else '_nospeed'}-d{args.days}"
                             f"-t{args.hindsight_trials}.json")
        if path.exists():
            results.append(json.loads(path.read_text(encoding="utf-8")))
        else:
            results.append(run_task(generator, seed, kind, args))
            path.write_text(json.dumps(results[-1], indent=1, default=float), encoding="utf-8")
        print(task_table(results[-1]), flush=True)
    print(summary(results))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=float), encoding="utf-8")


if __name__ == "__main__":
    main()
