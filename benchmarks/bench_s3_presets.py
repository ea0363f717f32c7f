"""S3's presets end to end: runs ``thermodrift run -m experiment=<preset>`` in a scratch folder, times it, and
prints S3's tables from the sweep's MLflow runs.

* ``s3_rbmox_dltk``: the Table 13/15 analogue per protocol (RMSE, MSE, MAE, R², EV, VAF of every arm and the MLR
  baseline), DLTK's RMSE reduction against BP, LSTM and TCN-LSTM, and the efficiency table (Table 14).
* ``s3_dltk_ablation``: one row per ablation tag with its metrics and parameter count.

    python benchmarks/bench_s3_presets.py s3_dltk_ablation
    python benchmarks/bench_s3_presets.py s3_rbmox_dltk --dir /tmp/s3 -- n_trials=4   # extra overrides after --
    python benchmarks/bench_s3_presets.py s3_rbmox_dltk --dir /tmp/s3 --tables-only   # tables of the last sweep
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

METRICS = ["rmse", "mse", "mae", "r2", "explained_variance", "vaf"]
EFFICIENCY = ["train_s", "latency_batch_ms", "latency_stream_ms", "n_parameters"]
ARM_NAMES = {("lstm", "sho"): "sho_lstm"}
BASELINES = ("mlr", "transfer_function")  # evaluated beside every arm on the same held-out rows


def children(uri: str):
    """The job runs of the newest sweep (parent run) in the tracking store at ``uri``."""
    import mlflow
    from mlflow.tracking import MlflowClient

    mlflow.set_tracking_uri(uri)
    client = MlflowClient()
    exp = client.get_experiment_by_name("thermodrift")
    parents = client.search_runs([exp.experiment_id], "tags.kind = 'sweep'", order_by=["attributes.start_time DESC"],
                                 max_results=1)
    if not parents:
        raise SystemExit(f"no sweep in {uri}")
    return client.search_runs([exp.experiment_id], f"tags.mlflow.parentRunId = '{parents[0].info.run_id}'")


def frame(runs):
    import pandas as pd

    rows = []
    for r in runs:
        t, m = r.data.tags, r.data.metrics
        arm = ARM_NAMES.get((t.get("model"), t.get("optimizer")), t.get("model"))
        row = {"arm": arm, "protocol": t.get("protocol"), "split": t.get("split"), "ablation": t.get("ablation"),
               "status": r.info.status}
        row.update({k: m.get(f"test/{k}") for k in METRICS})
        row.update({f"{b} rmse": m.get(f"baseline/{b}/test/rmse") for b in BASELINES})
        row.update({k: m.get(f"efficiency/{k}") for k in EFFICIENCY})
        rows.append(row)
    return pd.DataFrame(rows)


def print_rbmox(df) -> None:
    for protocol, part in df.groupby("protocol"):
        table = part.set_index("arm")[METRICS + [f"{b} rmse" for b in BASELINES]].sort_values("rmse")
        print(f"\nS3 Table 13/15 analogue, protocol={protocol} (split {part['split'].iloc[0]}), µm")
        print(table.to_string(float_format="%.4f"))
        if "dltk" in table.index:
            dltk = table.loc["dltk", "rmse"]
            red = {b: 100 * (1 - dltk / table.loc[b, "rmse"]) for b in ("bp", "lstm", "tcn_lstm") if b in table.index}
            for b in BASELINES:
                if table.loc["dltk", f"{b} rmse"] == table.loc["dltk", f"{b} rmse"]:  # not NaN: it was run
                    red[f"{b} (baseline)"] = 100 * (1 - dltk / table.loc["dltk", f"{b} rmse"])
            print("DLTK's RMSE reduction %: " + ", ".join(f"vs {k} {v:.1f}" for k, v in red.items()))
    honest = df[df["protocol"] == "honest"].set_index("arm")[EFFICIENCY]
    print("\nS3 Table 14 analogue (honest-split jobs): training s, latency ms per sample, parameters")
    print(honest.to_string(float_format="%.4f"))


def print_ablation(df) -> None:
    order = ["full", "no_deform", "no_lstm", "no_transformer", "no_kan"]
    table = df.set_index("ablation").reindex([o for o in order if o in set(df["ablation"])])
    print("\nS3 ablation analogue (honest split), µm")
    print(table[METRICS + ["n_parameters", "train_s"]].to_string(float_format="%.4f"))


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("preset", choices=["s3_rbmox_dltk", "s3_dltk_ablation"])
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
        start = time.perf_counter()
        code = subprocess.call(cmd, cwd=folder, stdout=subprocess.DEVNULL)
        print(f"{args.preset}: exit {code} after {(time.perf_counter() - start) / 60:.1f} min "
              f"(load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)")
    df = frame(children(uri))
    print(f"{len(df)} job runs: " + ", ".join(f"{s} {n}" for s, n in df["status"].value_counts().items()))
    done = df[df["status"] == "FINISHED"]
    if len(done):
        (print_rbmox if args.preset == "s3_rbmox_dltk" else print_ablation)(done)
    return 0


if __name__ == "__main__":
    sys.exit(main())
