"""``thermodrift calibrate``: fit a thermal network to a recording and map where it still misses.

Examples::

    thermodrift calibrate ../shared/data/fl_thermal/data.xlsx --manifest plugins/datasets/fl_thermal.yaml --out runs/cal
    thermodrift calibrate sim.csv --manifest sim.manifest.yaml --network demo_spindle --free 'edges.*.G_W_K'

Writes into ``--out``: ``calibration.json`` (estimates with confidence intervals, unidentifiable parameters and
null directions, noise σ, RMSE before/after, and for ``--network auto`` the baseline's assumptions),
``calibrated_network.yaml`` (the spec with the estimates written in), ``mismatch.json`` (residual shares per
channel and schedule window, ranked), ``mismatch_heatmap.png`` and ``before_after.png``. With
``--tracking-uri`` the same is logged to an MLflow run.

With ``--stochastic`` the calibrated network is then refined as a stochastic grey-box model
(:mod:`thermodrift.core.physics.stochastic.machine`): process noise on every node, measurement noise per channel,
one multiplier per calibrated parameter, all by maximum likelihood through the Kalman filter; ``stochastic.json``
holds the estimates with Hessian intervals, the unidentifiable ones, the innovations log-likelihood and each
channel's one-step residual whiteness.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from thermodrift.core.cli import options
from thermodrift.core.errors import InputError


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("table", help="recording table (CSV, Parquet or XLSX)")
    parser.add_argument("--manifest", required=True, help="manifest YAML of the table")
    parser.add_argument("--network", default="auto",
                        help="'auto' (baseline from the manifest alone, default), a spec YAML or a name in "
                             "conf/network")
    options.add_out(parser, "output folder", default="calibration")
    parser.add_argument("--targets", nargs="+", default=None, metavar="CHANNEL",
                        help="displacement channels to fit (default: all)")
    parser.add_argument("--free", action="append", default=None, metavar="PATTERN",
                        help="parameter paths to calibrate, globs allowed (repeatable; default: the network's "
                             "capacities, conductances and heat amplitudes)")
    parser.add_argument("--hidden-nodes", type=int, default=2, help="hidden nodes of the auto network (default 2)")
    parser.add_argument("--max-evaluations", type=int, default=100,
                        help="iteration cap of the search per start; it otherwise stops on its tolerances (default 100)")
    parser.add_argument("--starts", type=int, default=3,
                        help="starts of the search (the first at the start values, the rest jittered; default 3)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the jittered starts (default 0)")
    parser.add_argument("--level", type=float, default=0.95, help="confidence level of the intervals (default 0.95)")
    options.add_tracking_uri(parser, optional=True)
    parser.add_argument("--stochastic", action="store_true",
                        help="refine the calibration as a stochastic grey-box model (process noise, Kalman "
                             "likelihood); writes stochastic.json")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args: argparse.Namespace) -> int:
    import yaml
    from tqdm import tqdm

    from thermodrift.core.physics import calibration as cal
    from thermodrift.core.physics import mismatch
    from thermodrift.core.physics.spec import load_network, network_to_dict
    from thermodrift.core.recording import load_recording

    if not 0 < args.level < 1:
        raise InputError(f"--level must be in (0, 1), got {args.level}")
    if args.hidden_nodes < 0:
        raise InputError("--hidden-nodes must be ≥ 0")
    if args.max_evaluations < 1 or args.starts < 1:
        raise InputError("--max-evaluations and --starts must be ≥ 1")
    # The bar is closed (cleared) on any exit, so an error prints on a line of its own.
    with tqdm(total=4, desc="calibrate: loading", unit="step", disable=args.no_progress,
              leave=False) as steps:
        recording = load_recording(args.table, args.manifest)
        network = None if args.network == "auto" else load_network(args.network)
        steps.update()
        steps.set_description("calibrate: fitting")
        result = cal.calibrate(recording, network, free=args.free, targets=args.targets,
                               hidden_nodes=args.hidden_nodes, max_evaluations=args.max_evaluations,
                               starts=args.starts, seed=args.seed, level=args.level,
                               progress=not args.no_progress)
        steps.update()
        steps.set_description("calibrate: mismatch map")
        mm = mismatch.mismatch_map(result)
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "calibration.json").write_text(json.dumps(result.to_dict(), indent=1, ensure_ascii=False) + "\n",
                                              encoding="utf-8")
        (out / "calibrated_network.yaml").write_text(
            yaml.safe_dump(network_to_dict(result.network), allow_unicode=True, sort_keys=False), encoding="utf-8")
        (out / "mismatch.json").write_text(json.dumps(mm.to_dict(), indent=1, ensure_ascii=False) + "\n",
                                           encoding="utf-8")
        mismatch.plot_heatmap(mm, out / "mismatch_heatmap.png", speed=(result.time_s, result.speed_rpm))
        mismatch.plot_before_after(result, out / "before_after.png", mm)
        steps.update()
        if args.tracking_uri:
            from thermodrift.core import tracking

            steps.set_description("calibrate: logging")
            tracking.log_calibration(result, mm, out, args.tracking_uri, run_name=f"calibrate {Path(args.table).name}")
        steps.update()
    _print_summary(result, mm, out)
    if args.stochastic:
        _stochastic(result, recording, out, args.seed)
    return 0


def _stochastic(result, recording, out: Path, seed: int) -> None:
    """Refine ``result`` as a stochastic grey-box model; write and print its summary."""
    from thermodrift.core.physics.stochastic import fit, machine, whiteness

    factors = {e.name: tuple(e.paths) for e in result.estimates}
    model = machine.NetworkModel(result.network, recording, factors=factors)
    est = fit(model, model.data, seed=seed, starts=1)
    f = est.filtered()
    white = {c: whiteness.summary(f.standardized[:, k]) for k, c in enumerate(model.channels)}
    doc = {"network": result.network.name, "loglik": est.loglik, "n_params": est.n_params,
           "estimates": est.table(), "unidentifiable": est.unidentifiable, "whiteness": white,
           "channels": model.channels, "evaluations": est.n_evals, "seconds": round(est.seconds, 1)}
    (out / "stochastic.json").write_text(json.dumps(doc, indent=1, ensure_ascii=False, default=float) + "\n",
                                         encoding="utf-8")
    print(f"stochastic: log-likelihood {est.loglik:.1f} with {est.n_params} parameters ({est.n_evals} filter "
          f"passes, {est.seconds:.1f} s); one-step residuals white on "
          f"{sum(w['white'] for w in white.values())} of {len(white)} channels")
    if est.unidentifiable:
        print(f"  not identifiable: {', '.join(est.unidentifiable)}")


def _print_summary(result, mm, out: Path) -> None:
    import sys

    print(f"network {result.network.name!r}: {len(result.estimates)} parameters, {result.evaluations} simulations "
          f"in {result.seconds:.1f} s, stopped on {result.stop.replace('_', ' ')} ({result.stopped}); "
          f"fit grid {result.fit_samples} samples, step {result.grid_step_s:g} s")
    if result.prior is not None:
        held = result.prior.validation.get("held_out_s")
        print(f"prior on the nonlinear parameters: strength {result.prior.strength:g} per row"
              + (f", chosen on the held-out block {held[0]:g}–{held[1]:g} s" if held else ""))
    if len(result.starts) > 1:
        print(f"{len(result.starts)} starts: cost max/min {result.spread['cost_max_over_min']:.4g}")
    for w in result.warnings:
        print(f"WARNING: {w}", file=sys.stderr)
    print(f"objective {result.cost_initial:.4g} -> {result.cost:.4g}")
    print("RMSE before -> after:")
    for c in result.rmse:
        unit = "K" if result.channel_kind[c] == "temperature" else "um"
        print(f"  {c:<16} {result.rmse_initial[c]:9.3f} -> {result.rmse[c]:9.3f} {unit}")
    if result.unidentifiable:
        names = ", ".join(u["parameter"] for u in result.unidentifiable)
        print(f"not identifiable from this data ({len(result.unidentifiable)}): {names}")
    print("top mismatch windows (share of the weighted residual sum of squares):")
    for name, row in mm.by_window().head(5).iterrows():
        print(f"  {row['share']:6.1%}  {name}  (mostly {row['top_channel']})")
    print(f"wrote {out}")
