"""S3's presets end to end: runs ``thermodrift run -m experiment=<preset>`` in a scratch folder, reports its wall
clock, the CPU seconds of the run (what it costs on idle cores, even on a busy machine) and the load average, then
prints the preset's tables as ``thermodrift report`` builds them from the sweep's MLflow runs.

* ``s3_rbmox_dltk``: the Table 13/15 analogue per protocol, DLTK's RMSE reduction, the efficiency table (Table 14).
* ``s3_dltk_ablation``: the ablation table (five jobs tagged ablation=full, no_deform, ...).
* ``s3_selection``: Table 16 (PSO, GWO and FA tuning the selection's HDBSCAN).

    python benchmarks/bench_s3_presets.py s3_dltk_ablation
    python benchmarks/bench_s3_presets.py s3_rbmox_dltk --dir /tmp/s3 -- +s3_budget=paper   # overrides after --
    python benchmarks/bench_s3_presets.py s3_rbmox_dltk --dir /tmp/s3 --tables-only         # tables of the last sweep
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

TABLES = {"s3_rbmox_dltk": ("s3_table13", "s3_rmse_reduction", "s3_efficiency"), "s3_dltk_ablation": ("s3_ablation",),
          "s3_selection": ("s3_table16",)}


def newest_sweep(client) -> str:
    """The run id of the newest sweep (parent run) in the tracking store."""
    exp = client.get_experiment_by_name("thermodrift")
    parents = client.search_runs([exp.experiment_id], "tags.kind = 'sweep'", order_by=["attributes.start_time DESC"],
                                 max_results=1) if exp else []
    if not parents:
        raise SystemExit(f"no sweep in {client.tracking_uri}")
    return parents[0].info.run_id


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("preset", choices=list(TABLES))
    parser.add_argument("--dir", type=Path, default=None, help="scratch folder (default: /tmp/thermodrift-<preset>)")
    parser.add_argument("--tables-only", action="store_true", help="print the tables of the last sweep in --dir")
    args = parser.parse_args(argv)
    folder = (args.dir or Path(f"/tmp/thermodrift-{args.preset}")).resolve()
    folder.mkdir(parents=True, exist_ok=True)
    uri = f"sqlite:///{folder / 'mlflow.db'}"
    if not args.tables_only:
        cmd = ["thermodrift", "run", "-m", f"experiment={args.preset}", f"tracking.uri={uri}",
               f"optuna.storage=sqlite:///{folder / 'optuna.db'}", "progress=false", *extra]
        print("$ " + " ".join(cmd), flush=True)
        load = os.getloadavg()[0]
        start = time.perf_counter()
        code = subprocess.call(cmd, cwd=folder, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - start
        use = resource.getrusage(resource.RUSAGE_CHILDREN)
        print(f"{args.preset}: exit {code}; wall {wall / 60:.1f} min, CPU {use.ru_utime + use.ru_stime:.0f} s "
              f"(user + system of the run); load average {load:.1f} before, {os.getloadavg()[0]:.1f} after, "
              f"on {os.cpu_count()} cores")
    from mlflow.tracking import MlflowClient

    from thermodrift.core import report

    client = MlflowClient(uri)
    rows = report.collect(client, newest_sweep(client))
    for name in TABLES[args.preset]:
        heading, build = report.TABLES[name]
        print(f"\n## {heading}\n\n{report.markdown(build(rows))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
