"""Probe: would a mechanism's driver through a path of its own explain the ``auto`` baseline's drift residual?

The finder's candidates respond through the baseline's own structure (heat into a node the baseline has, read by
the sensitivities it fitted). On a machine that is not ours that structure is wrong, and a candidate's amplitude
fitted on some condition blocks does not transfer to the others (``docs/diagnose_experiments.md``). This probe asks
whether a response free of that structure would do better: the baseline's drift residual on the fitted rows is
regressed on a driver channel passed through a first-order lag of its own (the sensor model's
:func:`~thermodrift.core.physics.sensors.first_order_lag`, time constant τ; gain and offset solved by least
squares), and reported three ways, per τ:

* blocks   each condition block of the fitted rows left out in turn, the drop of its (block-centred) squared
           residual; the share of blocks improved and the t statistic of the drops (the finder's blocks line);
* active   the same over the blocks where the lagged driver varies (its block variance at least 1 % of the
           largest): the conditions in which the path acts;
* final    the drift RMSE on the final block that no fit saw, baseline and baseline + path (µm).

Nothing in the finder changes; the probe reads ``diagnose(...).baseline`` of the development cases of the
independent generators (``benchmarks/independent``)::

    python benchmarks/probe_private_path.py --driver cutting_power --cases fd:cutting_heat:2 lumped:cutting_heat:2
    python benchmarks/probe_private_path.py --driver ambient --cases fd:ambient_coupling:0 lumped:ambient_coupling:0 \\
        fd:none:500 fd:none:501 lumped:none:500
    python benchmarks/probe_private_path.py --driver coolant_inlet --cases fd:coolant_coupling:1 \\
        lumped:coolant_coupling:1 fd:none:501 fd:none:503
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from thermodrift.core.metrics import rms, rmse

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import independent  # noqa: E402

TAUS_H = (0.05, 0.25, 1.0, 4.0)
ACTIVE = 0.01  # a block is active when the lagged driver's variance there is at least this share of the largest


def _t(x: np.ndarray) -> float:
    sd = float(np.std(x, ddof=1)) if len(x) > 1 else 0.0
    return float(np.mean(x)) / (sd / np.sqrt(len(x))) if sd > 0 else float("nan")


def path_gain(residual: np.ndarray, x: np.ndarray, rows: np.ndarray, blocks: np.ndarray,
              final: np.ndarray) -> dict:
    """The regression of ``residual`` (µm, all samples) on ``x`` and an offset, fitted on ``rows`` (condition
    ``blocks`` per fitted row) and scored as the module docstring says."""
    X = np.column_stack([x, np.ones_like(x)])
    drops, spread = [], []
    for b in np.unique(blocks):
        train, test = rows[blocks != b], rows[blocks == b]
        beta = np.linalg.lstsq(X[train], residual[train], rcond=None)[0]
        before = residual[test] - residual[test].mean()
        after = residual[test] - X[test] @ beta
        drops.append(float(before @ before - (after - after.mean()) @ (after - after.mean())))
        spread.append(float(np.var(x[test])))
    drops, spread = np.array(drops), np.array(spread)
    active = spread >= ACTIVE * spread.max() if spread.max() > 0 else np.zeros(len(spread), bool)
    beta = np.linalg.lstsq(X[rows], residual[rows], rcond=None)[0]
    return {"wins": float(np.mean(drops > 0)), "t": _t(drops), "active": int(active.sum()),
            "blocks": len(drops), "active_wins": float(np.mean(drops[active] > 0)) if active.any() else float("nan"),
            "active_t": _t(drops[active]),
            "final_before": float(rms(residual[final])),
            "final_after": float(rmse(residual[final], X[final] @ beta))}


def probe(generator: str, hidden: str | None, seed: int, driver: str, folder: Path) -> list[dict]:
    """Rows of :func:`path_gain` per drift channel and τ for one development case."""
    from thermodrift.core.physics.diagnose import diagnose
    from thermodrift.core.physics.diagnose.windows import condition_blocks
    from thermodrift.core.physics.sensors import first_order_lag
    from thermodrift.core.recording import load_recording

    constant = {s_: c for s_, _, c in independent.case_list(False, 3, 20)}.get(seed, False)  # as the benchmark
    gen = independent.make_case(seed, hidden, constant_drivers=constant, generator=generator)
    gen.name = f"{generator}_{hidden or 'none'}_{seed}"
    rec = load_recording(*gen.write(folder))
    column = next((c for c in rec.data.columns if driver in c), None)
    if column is None:
        return [{"case": gen.name, "note": f"no {driver} channel"}]
    d = diagnose(rec, None, seed=0, max_rounds=1, bootstrap=10)
    rows = np.flatnonzero(d.fit_rows)
    blocks = condition_blocks(rec, rows)
    final = np.flatnonzero(~d.fit_rows)
    u = rec.data[column].to_numpy(dtype=float)
    out = []
    for j, (ch, kind) in enumerate(zip(d.channels, d.kinds)):
        if kind != "displacement":
            continue
        residual = d.measured[:, j] - d.baseline[:, j]
        for tau in TAUS_H:
            out.append({"case": gen.name, "channel": ch, "tau_h": tau,
                        **path_gain(residual, first_order_lag(u - u[0], d.time_s, tau * 3600.0), rows, blocks, final)})
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--driver", required=True, help="a substring of the driver column's name (cutting_power, "
                                                    "ambient, coolant_inlet, ...)")
    ap.add_argument("--cases", nargs="+", required=True, metavar="GEN:HIDDEN:SEED",
                    help="development cases, e.g. fd:cutting_heat:2 or lumped:none:500")
    args = ap.parse_args(argv)
    print("| case | channel | τ (h) | blocks improved | t | active blocks | active improved | active t | "
          "final block µm, baseline → + path |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory(prefix="probe-path-") as tmp:
        for spec in args.cases:
            generator, hidden, seed = spec.split(":")
            if int(seed) >= 1000:
                ap.error(f"{spec}: the probe reads development seeds only (< 1000); the sealed half stays sealed")
            for r in probe(generator, None if hidden == "none" else hidden, int(seed), args.driver, Path(tmp)):
                if "note" in r:
                    print(f"| {r['case']} | {r['note']} |")
                    continue
                print(f"| {r['case']} | {r['channel']} | {r['tau_h']:g} | {r['wins']:.2f} | {r['t']:.2f} | "
                      f"{r['active']}/{r['blocks']} | {r['active_wins']:.2f} | {r['active_t']:.2f} | "
                      f"{r['final_before']:.3f} → {r['final_after']:.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
