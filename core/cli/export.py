"""``thermodrift export RUN_ID --out DIR``: a logged run's model as a data-only compensator package.

The package (``package.json`` + ``arrays.npz``; ``weights.pt`` for networks, read with ``weights_only``; never a
pickle) holds the fitted model's exported state, the training range of every input, the safety defaults derived
from the training data, any fallback models, the sampling interval, the targets with their axes, and versions.
``thermodrift.compensator.load(DIR)`` reads it with numpy (scipy for physics, torch for networks). The package
is also logged on the run as the artifact folder ``compensator/``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from thermodrift.core.cli import options


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_id", metavar="RUN_ID", help="the MLflow run id that `thermodrift run` printed")
    options.add_out(parser, "folder to write the package into")
    options.add_tracking_uri(parser)


def run(args: argparse.Namespace) -> int:
    import json
    import platform
    import tempfile

    import numpy as np

    from thermodrift import compensator
    from thermodrift.compensator import package
    from thermodrift.core import artifacts, deployment, tracking
    from thermodrift.core.errors import InputError

    run_info = tracking.logged_run(args.tracking_uri, args.run_id)
    reason = run_info.data.tags.get("compensator") or run_info.data.tags.get("compensator_error")
    if reason:
        raise InputError(f"run {args.run_id}: {reason}", hint="export a run of a model that reads recorded channels")
    if deployment.LIMITS not in tracking.artifact_paths(args.run_id):
        raise InputError(f"run {args.run_id} has no {deployment.LIMITS!r} artifact",
                         hint="export a job run of `thermodrift run` (not a sweep's parent run); rerun the job "
                              "with this version if it was logged by an older one")
    with tempfile.TemporaryDirectory() as tmp:
        local = tracking.download(args.tracking_uri, args.run_id, None, tmp)
        model_dir = tracking.download(args.tracking_uri, args.run_id, "model", f"{tmp}/logged_model")
        if model_dir is None:
            raise InputError(f"run {args.run_id} has no logged model", hint="export a job run of `thermodrift run`")
        stored = next(p.parent for p in model_dir.rglob("model.json"))
        model = artifacts.load(stored)
        try:
            state = model.export_state()
        except NotImplementedError as exc:
            raise InputError(str(exc), hint="export a model of a family that has one (mlr, transfer_function, "
                                            "lptn, lptn_hybrid, lstm, AutoML pipelines)") from None
        limits = json.loads((local / deployment.LIMITS).read_text(encoding="utf-8"))
        fallbacks = {}
        if (local / deployment.FALLBACKS).is_dir():
            fallbacks = package.read(local / deployment.FALLBACKS)["fallbacks"]
    versions = {"thermodrift": _version(), "python": platform.python_version(), "numpy": np.__version__}
    if state.get("runtime") == "lptn":
        import scipy
        versions["scipy"] = scipy.__version__
    if state.get("runtime") == "sequence":
        import torch
        versions["torch"] = torch.__version__
    doc = package.document(state, limits, fallbacks=fallbacks, axes=limits.get("axes", {}), versions=versions,
                           source={"run_id": args.run_id, "tracking_uri": args.tracking_uri,
                                   "model": run_info.data.tags.get("model"),
                                   "dataset": run_info.data.tags.get("dataset")})
    out = package.write(doc, args.out)
    compensator.load(out)  # what was written loads
    tracking.client().log_artifacts(args.run_id, str(out), artifact_path="compensator")
    print(f"compensator package of run {args.run_id} (model {run_info.data.tags.get('model')}, "
          f"{len(state['inputs'])} inputs, targets {', '.join(state['targets'])}, "
          f"{len(fallbacks)} fallbacks) written to {out}; logged on the run as compensator/")
    return 0


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("thermodrift")
    except PackageNotFoundError:
        return "unknown"
