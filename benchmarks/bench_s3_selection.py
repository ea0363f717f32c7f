"""S3's selection study on the motorized_spindle_s3 recording: PSO against GWO and FA tuning HDBSCAN (S3 Table 16:
best correlation and the iteration it was first reached), the clustering quality of scikit-learn's default against
the tuned HDBSCAN, and the chosen cluster against 7 random sensors and against all 16 (held-out RMSE, µm).

Selection runs on the training part (first 70 % of time); the comparison model is MLR (fast, and the comparison is
about the inputs), refit on the training part and scored on the last 30 %. Random sensors: the mean over
``--random-draws`` draws of 7.

    python benchmarks/bench_s3_selection.py                      # 25 iterations of swarm 20 (500 trials) each
    python benchmarks/bench_s3_selection.py --iterations 100     # S3's budget (2,000 trials per optimizer)
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=25)
    parser.add_argument("--optimizers", nargs="+", default=["pso", "gwo", "fa"])
    parser.add_argument("--random-draws", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    import pandas as pd

    from thermodrift.core import registry
    from thermodrift.core.recording import TEMPERATURE_ROLES
    from thermodrift.core.metrics import evaluate

    pd.set_option("display.width", 160)
    rec = registry.create("dataset", "motorized_spindle_s3")
    X = rec.data[[c for r in TEMPERATURE_ROLES for c in rec.columns(r)]]
    y = rec.data[rec.columns("displacement")]
    cut = int(0.7 * len(X))
    print(f"motorized_spindle_s3: {X.shape[1]} sensors, selection on the first {cut} of {len(X)} samples; "
          f"{args.iterations} iterations of 20; seed {args.seed}; load average {os.getloadavg()[0]:.1f}")

    rows, chosen = [], None
    for name in args.optimizers:
        params = {"population_size": 20}
        start = time.perf_counter()
        sel = registry.create("selector", "hdbscan_pso", optimizer=name, optimizer_params=params,
                              n_iterations=args.iterations, random_state=args.seed).fit(X.iloc[:cut], y.iloc[:cut])
        seconds = time.perf_counter() - start
        conv = sel.report_["convergence"]["best_fitness"]
        first = int(conv.index[np.argmax(conv.to_numpy() >= conv.max() - 1e-12)])
        rows.append({"optimizer": name, "best |r|": sel.fitness_, "reached at iteration": first,
                     "sensors": ",".join(sel.selected_), "seconds": seconds})
        if name == args.optimizers[0]:
            chosen = sel
    print("\nS3 Table 16 analogue: the optimizers on HDBSCAN's hyper-parameters (fitness: best cluster |Pearson r|)")
    print(pd.DataFrame(rows).set_index("optimizer").to_string(float_format="%.5f"))

    print(f"\nclusters of the tuned clustering ({args.optimizers[0]}), ranked")
    print(chosen.report_["clusters"].to_string(float_format="%.4f"))
    print("\nclustering quality: scikit-learn's default HDBSCAN vs tuned (noise sensors count as singletons)")
    print(chosen.report_["quality"].to_string(float_format="%.4f"))

    def rmse(cols: list[str]) -> float:
        model = registry.create("model", "mlr").fit(X.iloc[:cut][cols], y.iloc[:cut])
        return evaluate(y.iloc[cut:], model.predict(X.iloc[cut:][cols]))["mean"]["rmse"]

    rng = np.random.default_rng(args.seed)
    random7 = [rmse(list(rng.choice(X.columns, size=7, replace=False))) for _ in range(args.random_draws)]
    table = pd.DataFrame({"sensors": [len(chosen.selected_), 7, X.shape[1]],
                          "held-out RMSE µm (MLR)": [rmse(chosen.selected_), float(np.mean(random7)),
                                                     rmse(list(X.columns))]},
                         index=["chosen cluster", f"7 random (mean of {args.random_draws})", "all sensors"])
    base = table.iloc[0, 1]
    table["chosen vs this"] = [np.nan] + [1 - base / v for v in table.iloc[1:, 1]]
    print("\nthe chosen cluster against 7 random sensors and all sensors (last 30 % of time held out)")
    print(table.to_string(float_format="%.3f"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
