"""Adequacy first: the auto baseline's structure chosen on held-out data, and how adequate the result is.

Before mechanisms compete to explain the residual, the structural misfit the baseline itself can shed is shed:
the ``auto`` network is calibrated on the screening rows before the inner validation block with each set of
hidden nodes in :data:`HIDDEN_OPTIONS` (unmeasured heat paths that act on the displacements only, each adding
a time constant to the expansion map) and the set that predicts the validation block best (noise-weighted,
temperature and displacement channels balanced) is kept; a larger set must beat a smaller one by
:data:`MIN_GAIN` of its held-out error. Then the expansion map (:func:`choose_lags`): the auto map reads every
node instantaneously, but the part that expands is seldom where its sensor sits (a shaft behind a housing
sensor, a casting behind a surface pad) and follows it through a conduction delay. Each drift channel may also
read every temperature node through a first-order lag (:data:`LAG_OPTIONS`, shorter than the slow structural
mode the finder tests), its sensitivities solved linearly beside the direct ones, so that lead and lag are both
expressible; a lag is kept only when it cuts the drift error by :data:`MIN_GAIN` on the validation block and
on the inner condition blocks, each left out in turn. Links to the coolant or extra ambient paths are mechanisms
the finder tests (``coolant_coupling``, ``ambient_coupling``): adding them here would hide what it is asked to
find. The search happens in :func:`thermodrift.core.physics.diagnose.diagnose` only; the ``auto`` network that ``lptn``
and ``lptn_hybrid`` calibrate keeps its default.

:func:`assess` then says how adequate the chosen baseline is: its fitted drift error against the drift sensors'
noise, the correlation of its residual (the noise model's AR coefficient sum, :mod:`.noise`) and its error on
the inner validation block against its fitted error.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from thermodrift.core.metrics import rms, rmse
from thermodrift.core.physics.calibration import calibrate
from thermodrift.core.physics.diagnose.windows import condition_blocks
from thermodrift.core.physics.network import Edge, Network, Node, TemperatureSensor

# Hidden nodes by their start time constants (h): the auto network's default pair, one more with a fast path
# (minutes: heat that reaches the structure quicker than any surface sensor shows it) and a finer spread.
HIDDEN_OPTIONS = ((0.5, 4.0), (0.1, 0.7, 4.0), (0.1, 0.5, 1.5, 4.0))
MIN_GAIN = 0.05
# Lags (h) through which the drift channels may read the temperature nodes, tried one at a time after none: a
# conduction delay between a sensor and the part that expands, below the slow structural mode's 0.5 h bound.
LAG_OPTIONS = ((0.1,), (0.25,))
LAG_PREFIX = "lag_"
LAG_GROUP = "reading"  # the network group of a lagged reading: no mechanism is placed on it
LAG_CAPACITY_J_K = 1.0  # a lag node draws ~1e-4 of its source node's heat flow: it reads, it does not cool
STRUCTURAL_RATIO = 2.0  # fitted drift error over this many noise σ: misfit beyond noise (structural)
# Held-out drift error (RMS over the drift channels of the inner validation block, the baseline's linear map solved
# without it) over this many noise σ: structural misfit, and only a mechanism that accounts for it is named
# (:mod:`.rule`). A model right up to its parameters leaves noise there: the mean square of n white samples of
# unit variance exceeds 4 (RMS 2) with chance far below 1e-6 at the ~100 samples a validation block holds.
HELD_OUT_RATIO = 2.0


def _balanced_error(measured: np.ndarray, readings: np.ndarray, sigma: np.ndarray, kinds: list[str],
                    rows: np.ndarray) -> float:
    """Mean squared noise-weighted error on ``rows``, temperature and displacement channels weighing half each."""
    err = (((measured - readings) / sigma)[rows]) ** 2
    groups = [np.array([k == kind for k in kinds]) for kind in ("temperature", "displacement")]
    parts = [float(err[:, g].mean()) for g in groups if g.any()]
    return float(np.mean(parts))


def choose_hidden(recording, inner_rows: np.ndarray, val_rows: np.ndarray, scenario, evaluations: int,
                  baseline_of, jitter_seed: int | None = None) -> tuple[tuple[float, ...], list[dict[str, Any]], Any]:
    """The hidden nodes (start time constants, h) of the auto baseline that predicts ``val_rows`` best when
    calibrated on ``inner_rows`` (indices into ``recording``), the table of every set tried (held-out error
    in noise units) and that calibration. ``baseline_of`` is the screening's linear refit
    (:func:`.screening.baseline_of`); ``jitter_seed`` starts every calibration from a jittered start instead of the
    declared one (the calibration's own jitter; ``benchmarks/probe_hidden_starts.py``)."""
    inner_rec = recording.select(np.isin(np.arange(len(recording)), inner_rows))
    table, best = [], None
    for h in HIDDEN_OPTIONS:
        cal = calibrate(inner_rec, None, hidden_nodes=h, intervals=False, max_evaluations=evaluations,
                        prior_strength=0.0, jitter_seed=jitter_seed)
        channels = list(cal.sigma)
        kinds = [cal.channel_kind[c] for c in channels]
        sigma = np.array([cal.sigma[c] for c in channels])
        measured = recording.data[channels].to_numpy(dtype=float)
        readings = baseline_of(cal.network, scenario, channels, measured, inner_rows, sigma).readings
        err = _balanced_error(measured, readings, sigma, kinds, val_rows)
        fit_err = _balanced_error(measured, readings, sigma, kinds, inner_rows)
        table.append({"hidden_nodes": len(h), "time_constants_h": list(h), "heldout_error": round(err, 4),
                      "fitted_error": round(fit_err, 4)})
        if best is None or err < (1 - MIN_GAIN) * best[1]:
            best = (h, err, cal)
    for row in table:
        row["chosen"] = tuple(row["time_constants_h"]) == best[0]
    return best[0], table, best[2]


def with_lags(network: Network, lags_h: tuple[float, ...]) -> Network:
    """``network`` with, for every node read by a temperature sensor and every lag τ (h), an unmeasured node of
    negligible capacity following it through a first-order lag τ and entering every output's expansion map
    (sensitivity 0 µm/K, solved linearly by :func:`.screening.baseline_of`)."""
    read = [n for s in network.sensors if isinstance(s, TemperatureSensor) for n in s.weights
            if n in network.node_names]
    added = []
    for node in dict.fromkeys(read):
        for tau in lags_h:
            lag = f"{LAG_PREFIX}{node}_{round(tau * 60)}min"
            added += [Node(lag, LAG_CAPACITY_J_K, LAG_GROUP),
                      Edge(f"{node}-{lag}", node, lag, LAG_CAPACITY_J_K / (tau * 3600.0), kind="conduction")]
    lagged = [n.name for n in added if isinstance(n, Node)]
    outputs = [dataclasses.replace(o, sensitivity_um_K={**o.sensitivity_um_K, **{n: 0.0 for n in lagged}})
               for o in network.outputs]
    return network.add(*added).replace(*outputs).validate()


def is_lag_node(network: Network, name: str) -> bool:
    """Whether ``name`` is a lagged reading in ``network`` (a node of group :data:`LAG_GROUP`, as
    :func:`with_lags` adds): no mechanism is placed on it."""
    return name in network.node_names and network.node(name).group == LAG_GROUP


def choose_lags(cal, recording, inner_rows: np.ndarray, val_rows: np.ndarray, scenario,
                baseline_of) -> tuple[tuple[float, ...], list[dict[str, Any]]]:
    """The lags (h) of the expansion map (:func:`with_lags`; ``()`` for none) for the calibration ``cal`` made
    on ``inner_rows``, and the table of every option tried: the drift channels' noise-weighted error on
    ``val_rows`` (the map solved on ``inner_rows``) and on the inner condition blocks (each solved without it).
    An option is kept when both errors fall by :data:`MIN_GAIN` against the best so far."""
    network, channels = cal.network, list(cal.sigma)
    disp = np.array([cal.channel_kind[c] == "displacement" for c in channels])
    measured = recording.data[channels].to_numpy(dtype=float)
    sigma = np.array([cal.sigma[c] for c in channels])
    blocks = condition_blocks(recording, inner_rows)
    table, best = [], None
    for lags in ((),) + LAG_OPTIONS:
        net = with_lags(network, lags) if lags else network

        def drift_error(fit, score):
            readings = baseline_of(net, scenario, channels, measured, fit, sigma).readings
            return float(((((measured - readings) / sigma)[score][:, disp]) ** 2).mean())

        val = drift_error(inner_rows, val_rows)
        cv = float(np.mean([drift_error(inner_rows[blocks != b], inner_rows[blocks == b])
                            for b in np.unique(blocks)]))
        table.append({"lags_h": list(lags), "heldout_drift_error": round(val, 4), "blocks_drift_error": round(cv, 4)})
        if best is None or (val < (1 - MIN_GAIN) * best[1] and cv < (1 - MIN_GAIN) * best[2]):
            best = (lags, val, cv)
    for row in table:
        row["chosen"] = tuple(row["lags_h"]) == best[0]
    return best[0], table


def assess(channels: list[str], kinds: list[str], sigma: np.ndarray, measured: np.ndarray, readings: np.ndarray,
           rows: np.ndarray, val_rows: np.ndarray, val_readings: np.ndarray, noise) -> dict[str, Any]:
    """How adequate the baseline is, per displacement channel: fitted RMSE (µm) and its ratio to the noise σ,
    the inner validation block's RMSE (fitted without it) and its ratio to the fitted one, and the residual's
    AR coefficient sum; ``structural`` when some drift channel misses by over :data:`STRUCTURAL_RATIO` σ.
    ``heldout_structural`` is the measure the rule reads (:func:`heldout_misfit`), computed before any mechanism is
    tested."""
    out: dict[str, Any] = {"channels": {}}
    ar = noise.describe(channels)
    for j, (c, k) in enumerate(zip(channels, kinds)):
        if k != "displacement":
            continue
        fit = float(rmse(measured[rows, j], readings[rows, j]))
        val = float(rmse(measured[val_rows, j], val_readings[val_rows, j])) if len(
            val_rows) else float("nan")
        out["channels"][c] = {"rmse_um": round(fit, 4), "noise_um": round(float(sigma[j]), 4),
                              "misfit_over_noise": round(fit / sigma[j], 2),
                              "validation_rmse_um": round(val, 4),
                              "validation_over_fitted": round(val / fit, 2) if fit > 0 else None,
                              "residual_ar_sum": ar[c]["phi_sum"]}
    out["structural"] = any(v["misfit_over_noise"] > STRUCTURAL_RATIO for v in out["channels"].values())
    out["heldout_structural"] = heldout_misfit(kinds, sigma, measured, val_rows, val_readings)
    return out


def heldout_misfit(kinds: list[str], sigma: np.ndarray, measured: np.ndarray, val_rows: np.ndarray,
                   val_readings: np.ndarray) -> dict[str, Any]:
    """The baseline's structural-misfit measure on held-out data: the RMS of its drift residual on the inner
    validation block (``val_readings``: its linear map solved without that block), over all drift channels, in
    units of each channel's noise σ; ``structural`` when over :data:`HELD_OUT_RATIO`."""
    disp = np.array([k == "displacement" for k in kinds])
    if not len(val_rows) or not disp.any():
        return {"rms_over_noise": None, "threshold": HELD_OUT_RATIO, "structural": False}
    z = ((measured - val_readings) / sigma)[val_rows][:, disp]
    ratio = float(rms(z))
    return {"rms_over_noise": round(ratio, 3), "threshold": HELD_OUT_RATIO, "structural": ratio > HELD_OUT_RATIO}
