"""Stochastic grey-box identification benchmark: forward selection, intervals and HTC on simulated houses, and
the selected model against the one-state model on the three real houses.

Simulation (``--cases N``, default 1 per simulator: the one-state house, about 6 min on the shared two-core
machine at load 20; a forward selection on a larger structure takes 10–15 min there): houses of every structure of the building library in turn
(:func:`benchmarks.independent.house_sde.case_list`: 24 structures, parameters drawn around realistic values,
60 days at 15 min, winter weather, a thermostat), recorded two ways:

* ``independent`` — :mod:`benchmarks.independent.house_sde`, which shares no code with the library: Euler–
  Maruyama on a 10 s step, the heating closed-loop on the measured temperature;
* ``engine`` — the library's own sampler (:func:`thermodrift.core.physics.stochastic.simulate`, exact discrete
  steps) of the same structure and true parameters, driven by the independent recording's weather and heating.

Each recording goes through forward selection from ``building_ti`` (:mod:`thermodrift.core.physics.stochastic.
selection`, its defaults). Scored: the selected structure equals the truth; on the recovered cases, the share of
parameters whose 95 % interval holds the true value (all parameters, and those not named unidentifiable); the
selected model's HTC within 10 % of the true HTC.

Seeds: the development half (seeds from 0); ``--sealed`` runs the sealed half (seeds from 10000,
``house_sde.SEALED_FROM``) — fixed before it was first run and run once, reported separately.

Real houses (``--houses``): ``blg_1..3`` from ``--buildings`` (default ``$THERMODRIFT_BUILDINGS``, else
../shared/data/buildings from the current directory, as the ``buildings`` dataset looks); the last 14 days held out, forward selection on the rest; per house the selected model's and the
one-state model's RMSE (K) of the 24 h-ahead (k = 96) predictions on the held-out part (the Kalman filter run
over the whole recording with the fitted parameters; ŷ_j|j−96 from the inputs over the day). Nothing is tuned to
these houses.

Run::

    python benchmarks/bench_greybox.py                     # 1 case per simulator, under 10 min on 2 cores
    python benchmarks/bench_greybox.py --cases 24          # every structure once per simulator
    python benchmarks/bench_greybox.py --sealed --cases 24 # the sealed half, once
    python benchmarks/bench_greybox.py --houses --cases 0 --workers 2  # the three real houses only, as diagnose
    python benchmarks/bench_greybox.py --pick 1 5 9        # only those cases of the list (0-based)

``--json FILE`` writes every case. ``--workers N`` fits a round's candidates in N processes (``diagnose`` uses
min(2, cores); the result does not depend on it). Per selection it reports the wall time (a shared machine:
noisy), the CPU time of this process and its workers, and the filter passes (a gradient pass counts one).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.independent import house_sde  # noqa: E402
from thermodrift.core import registry  # noqa: E402
from thermodrift.core.metrics import rmse  # noqa: E402
from thermodrift.core.physics import stochastic as sto  # noqa: E402
from thermodrift.core.physics.stochastic.building import PARTS  # noqa: E402
from thermodrift.core.physics.stochastic.selection import forward_select  # noqa: E402

SAMPLE_H = house_sde.SAMPLE_H
HOLDOUT_DAYS = 14
K_DAY = int(round(24 / SAMPLE_H))
# the independent simulator's parameter names where the library's differ
NAME = {"sigma_i": "sigma_ti", "sigma_m": "sigma_tm", "sigma_e": "sigma_te", "sigma_h": "sigma_th",
        "sigma_s": "sigma_ts"}


def network(structure: str):
    """The library's network of ``structure``: building_ti extended by each part, in the field's order."""
    states, aeria = house_sde.parse(structure)
    net = sto.load("building_ti")
    for part in list(states[1:]) + (["AeRia"] if aeria else []):
        net = registry.create("mechanism", PARTS[part]).apply(net)
    return net


def truth(house: house_sde.House) -> dict[str, float]:
    """The true parameters in the library's names (the measurement noise is ``sigma_y``)."""
    out = {NAME.get(k, k): v for k, v in house.params.items()}
    out["sigma_y"] = house.meas_sd
    return out


def series(net, df: pd.DataFrame) -> "sto.Series":
    """The library's series of a recording (times in h; inputs Ta, Ps, heating in the network's order)."""
    cols = {net.input_of("ambient"): "Ta", net.input_of("solar_irradiance"): "Ps", net.input_of("heating"): "Thm"}
    t = (df["t"] - df["t"].iloc[0]).dt.total_seconds().to_numpy() / 3600.0
    return sto.Series.of(t, df[[cols[c] for c in net.input_names]].to_numpy(float), df[["yTi"]].to_numpy(float))


def engine_recording(house: house_sde.House, df: pd.DataFrame, seed: int) -> pd.DataFrame:
    """The library's own sample path of the true model under the independent recording's inputs."""
    net = network(house.structure)
    values = truth(house)
    system = net.system({p.name: values[p.name] for p in net.params})
    out = df.copy()
    out["yTi"] = sto.simulate(system, series(net, df), seed=seed)[:, 0]
    return out


def cpu_seconds() -> float:
    """CPU time of this process and of its finished children (the selection's worker processes), s."""
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))


def score_case(house: house_sde.House, df: pd.DataFrame, seed: int, workers: int = 1) -> dict:
    """Forward selection on one recording, scored against the truth."""
    base = sto.load("building_ti")
    cpu = cpu_seconds()
    sel = forward_select(base, series(base, df), seed=seed, workers=workers)
    cpu = cpu_seconds() - cpu
    est = sel.selected.estimate
    found = sto.structure_name(est.model)
    got_htc, htc_ci = est.derived(lambda v: sto.htc(est.model, v))
    row = {"structure": house.structure, "selected": found, "recovered": found == house.structure,
           "path": [s.name for s in sel.path], "htc_true": house.htc, "htc": got_htc,
           "htc_ci": list(htc_ci) if htc_ci else None, "htc_rel_err": abs(got_htc / house.htc - 1.0),
           "seconds": round(sel.seconds, 1), "cpu_seconds": round(cpu, 1), "filter_passes": sel.n_evals,
           "loglik": est.loglik, "covered": {}, "unidentifiable": sorted(est.unidentifiable)}
    if row["recovered"]:
        true = truth(house)
        for name, (lo, hi) in est.intervals.items():
            if lo is not None and name in true:
                row["covered"][name] = bool(lo <= true[name] <= hi)
    return row


def simulation(cases: int, sealed: bool, sims: list[str], log, pick: list[int] | None = None, base: int = 0,
               workers: int = 1) -> list[dict]:
    rows = []
    listed = house_sde.case_list(sealed, max([cases, *(i + 1 for i in pick or ())]), base)
    for seed, structure in ([listed[i] for i in pick] if pick else listed):
        house, df = house_sde.make_case(seed, structure)
        for sim in sims:
            rec = df if sim == "independent" else engine_recording(house, df, seed)
            row = {"sim": sim, "seed": seed, **score_case(house, rec, seed, workers)}
            rows.append(row)
            cov = row["covered"]
            log(f"{sim:11s} seed {seed:5d} {structure:16s} -> {row['selected']:16s} "
                f"HTC err {100 * row['htc_rel_err']:5.1f} %  covered {sum(cov.values())}/{len(cov)}  "
                f"loglik {row['loglik']:.1f}  {row['seconds']:.0f} s wall, {row['cpu_seconds']:.0f} s CPU, "
                f"{row['filter_passes']} passes  ({' > '.join(row['path'])})")
    return rows


def summary(rows: list[dict]) -> list[dict]:
    out = []
    for sim in sorted({r["sim"] for r in rows}):
        rs = [r for r in rows if r["sim"] == sim]
        rec = [r for r in rs if r["recovered"]]
        cov = [c for r in rec for c in r["covered"].values()]
        cov_id = [c for r in rec for k, c in r["covered"].items() if k not in r["unidentifiable"]]
        out.append({"sim": sim, "cases": len(rs), "recovered": len(rec) / len(rs),
                    "coverage": float(np.mean(cov)) if cov else float("nan"), "n_params": len(cov),
                    "coverage_identifiable": float(np.mean(cov_id)) if cov_id else float("nan"),
                    "n_identifiable": len(cov_id),
                    "htc_within_10pct": float(np.mean([r["htc_rel_err"] <= 0.10 for r in rs])),
                    "median_seconds": float(np.median([r["seconds"] for r in rs]))})
    return out


def read_house(path: Path) -> pd.DataFrame:
    df = pd.read_csv(path, sep=";", index_col=0, parse_dates=["t"])
    return df[["t", "Ta", "Ps", "Thm", "yTi"]]


def real_house(path: Path, seed: int, log, workers: int = 1) -> dict:
    """Forward selection on all but the last 14 days; 24 h-ahead RMSE (K) of the selected and the one-state model
    on those days."""
    df = read_house(path)
    cut = len(df) - HOLDOUT_DAYS * K_DAY
    base = sto.load("building_ti")
    full = series(base, df)
    cpu = cpu_seconds()
    sel = forward_select(base, full.rows(0, cut), seed=seed, workers=workers)
    cpu = cpu_seconds() - cpu
    y = full.y[cut:, 0]
    out = {"house": path.stem, "rows": len(df), "fit_rows": cut, "selected": sel.selected.name,
           "loglik": sel.selected.estimate.loglik,
           "path": [s.record() | {"candidates": None} for s in sel.path], "seconds": round(sel.seconds, 1),
           "cpu_seconds": round(cpu, 1), "filter_passes": sel.n_evals, "workers": workers}
    for label, est in (("selected", sel.selected.estimate), ("ti", sel.path[0].estimate)):
        f = est.filtered(full)
        pred = sto.k_step(est.system, full, f, K_DAY)[cut:, 0]
        one = full.y[cut:, 0] - f.e[cut:, 0]
        out[f"rmse24_{label}"] = rmse(pred, y)
        out[f"rmse1_{label}"] = rmse(one, y)
    log(f"{path.stem}: {' -> '.join(s.name for s in sel.path)}  selected {out['selected']}  24 h RMSE "
        f"{out['rmse24_selected']:.3f} K vs Ti {out['rmse24_ti']:.3f} K  loglik {out['loglik']:.1f}  "
        f"({out['seconds']:.0f} s wall, {out['cpu_seconds']:.0f} s CPU, {workers} workers, "
        f"{out['filter_passes']} filter passes)")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=1, help="simulated houses per simulator")
    ap.add_argument("--sealed", action="store_true", help="the sealed seed half (run once, at the end)")
    ap.add_argument("--base", type=int, default=0, help="first seed within the half (a fresh range: e.g. 100)")
    ap.add_argument("--pick", nargs="+", type=int, help="only these cases of the list (0-based; instead of --cases)")
    ap.add_argument("--sims", nargs="+", default=["independent", "engine"], choices=["independent", "engine"])
    ap.add_argument("--houses", nargs="*", type=int, choices=(1, 2, 3),
                    help="also the real houses (all three without numbers; 24 h ahead on the last 14 days)")
    ap.add_argument("--buildings", type=Path,
                    default=Path(os.environ.get("THERMODRIFT_BUILDINGS", "../shared/data/buildings")))
    ap.add_argument("--json", type=Path, help="write every case here")
    ap.add_argument("--workers", type=int, default=1,
                    help="processes fitting a round's candidates (diagnose uses the cores, at most 2)")
    args = ap.parse_args(argv)
    clock = time.perf_counter()
    result: dict = {"sealed": args.sealed}

    def log(line: str) -> None:
        print(line, flush=True)

    if args.cases or args.pick:
        rows = simulation(args.cases, args.sealed, args.sims, log, args.pick, args.base, args.workers)
        result["cases"], result["summary"] = rows, summary(rows)
        print(f"\n{'half':9s} {'simulator':12s} {'cases':>5s} {'recovered':>9s} {'CI cover':>13s} "
              f"{'(identif.)':>13s} {'HTC ±10%':>8s}")
        for s in result["summary"]:
            print(f"{'sealed' if args.sealed else 'dev':9s} {s['sim']:12s} {s['cases']:5d} "
                  f"{100 * s['recovered']:8.0f}% {100 * s['coverage']:6.1f}% of {s['n_params']:3d} "
                  f"{100 * s['coverage_identifiable']:6.1f}% of {s['n_identifiable']:3d} "
                  f"{100 * s['htc_within_10pct']:7.0f}%")
        print("targets: recovered >= 90 %, 95 % intervals cover 90-98 %, HTC within 10 % on >= 90 %")
    if args.houses is not None:
        houses = [real_house(args.buildings / f"blg_{k}.csv", 0, log, args.workers) for k in (args.houses or (1, 2, 3))]
        result["houses"] = houses
        print(f"\n{'house':7s} {'selected':16s} {'24 h RMSE sel':>13s} {'24 h RMSE Ti':>12s} {'ratio':>6s} "
              f"{'1-step sel':>10s} {'1-step Ti':>9s}")
        for h in houses:
            print(f"{h['house']:7s} {h['selected']:16s} {h['rmse24_selected']:11.3f} K {h['rmse24_ti']:10.3f} K "
                  f"{h['rmse24_selected'] / h['rmse24_ti']:6.2f} {h['rmse1_selected']:8.3f} K "
                  f"{h['rmse1_ti']:7.3f} K")
    print(f"\nwall {time.perf_counter() - clock:.0f} s (a shared machine: noisy)")
    if args.json:
        args.json.write_text(json.dumps(result, indent=1, default=float), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
