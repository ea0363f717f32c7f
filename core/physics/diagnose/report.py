"""What :func:`thermodrift.core.physics.diagnose.diagnose` found, written for people and for outside checks.

``report.json`` has exactly the shape outside checks read (channel keys are the recording's displacement
channels; ``rmse_um`` over the data the models were fitted on, ``heldout_rmse_um`` over the final block that
neither screening, selection nor fitting saw)::

    {"baseline": {"rmse_um": {ch: x}, "heldout_rmse_um": {ch: x}},
     "findings": [{"mechanism", "confidence", "parameters", "ci", "where": [{"channel", "start_s", "end_s"}],
                   "evidence"}],
     "rejected": [{"mechanism", "reason"}],
     "augmented": {"rmse_um": {...}, "heldout_rmse_um": {...}},
     "verdict": "one paragraph"}

Keys added besides (never renamed): per finding ``test``, ``statistic``, ``dof``, ``p_value``, ``fdr_level``,
``fixed`` (parameters the data cannot identify, held at their fitted value), ``label`` and ``route`` (which
evidence passed it: the likelihood ratio, blocks and held-out gain, or a decisive held-out gain with the blocks,
whose t statistic, degrees of freedom and p-value are then ``statistic``, ``dof`` and ``p_value``); at the top level
``adequacy`` (:func:`thermodrift.core.physics.diagnose.adequacy.assess`: the baseline's misfit against noise,
its residual's correlation, its validation error against its fitted error, the hidden-node counts tried and
``expansion_lags``, the expansion map's lags tried).

Besides it: ``report.md``, ``residuals.csv`` (measured minus baseline and augmented prediction per channel and
sample, with the final-block flag), ``residual_map.png`` (before and after), ``fit.png`` (each displacement
channel: measured, baseline, augmented). Logging them to MLflow is the verb's
(:func:`thermodrift.core.tracking.log_diagnosis`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from thermodrift.core.metrics import rms, rmse


def _r(x: float) -> float:
    return round(float(x), 4)


def to_json(d) -> dict[str, Any]:
    fit, final = d.fit_rows, ~d.fit_rows
    findings = [{k: f[k] for k in ("mechanism", "confidence", "parameters", "ci", "where", "evidence", "test",
                                   "statistic", "dof", "p_value", "fdr_level", "fixed", "label", "route") if k in f}
                for f in d.findings]
    return {
        "baseline": {"rmse_um": {c: _r(v) for c, v in d.rmse(d.baseline, fit).items()},
                     "heldout_rmse_um": {c: _r(v) for c, v in d.rmse(d.baseline, final).items()}},
        "findings": findings,
        "rejected": [{"mechanism": r["mechanism"], "reason": r["reason"]} for r in d.rejected],
        "augmented": {"rmse_um": {c: _r(v) for c, v in d.rmse(d.augmented, fit).items()},
                      "heldout_rmse_um": {c: _r(v) for c, v in d.rmse(d.augmented, final).items()}},
        "verdict": verdict(d),
        "adequacy": d.adequacy,
    }


def _what(mechanism: str) -> str:
    """The mechanism's one-line ``summary`` (its name in words where it declares none)."""
    return getattr(_mechanism(mechanism), "summary", "") or mechanism.replace("_", " ")


def _mechanism(mechanism: str):
    from thermodrift.core import registry

    return registry.default().get("mechanism", mechanism).factory


def _structural(d) -> str:
    """A sentence on how far the baseline's drift misfit exceeds noise, empty when it does not."""
    a = getattr(d, "adequacy", {}) or {}
    if not a.get("structural"):
        return ""
    return "; ".join(f"{c}: {v['rmse_um']:.3g} µm fitted, {v['misfit_over_noise']:.3g} times the probe noise, "
                     f"residual AR coefficient sum {v['residual_ar_sum']:.3g}" for c, v in a["channels"].items())


def verdict(d) -> str:
    final = ~d.fit_rows
    before, after = d.rmse(d.baseline, final), d.rmse(d.augmented, final)
    drift = "; ".join(f"{c} {before[c]:.2f} → {after[c]:.2f} µm" for c in before)
    fitted = d.rmse(d.baseline, d.fit_rows)
    far = [c for c in before if before[c] > 3 * fitted[c]]
    outside = (f" The calibrated model itself misses the final block by over 3 times its fitted error on "
               f"{', '.join(far)}: that block's conditions lie outside those it was fitted on." if far else "")
    structural = _structural(d)
    if not d.findings:
        head = ("Nothing is missing as far as this data can tell: no mechanism in the library explains what the "
                "calibrated model misses (every candidate failed the whitened likelihood-ratio test at the "
                "stated false-discovery level, the held-out condition blocks or the held-out validation block; "
                "see rejected). ")
        if structural:
            head = ("The calibrated model misses more than noise, and no mechanism in the library explains it: the "
                    f"misfit is structural ({structural}). It is not that nothing is missing: the baseline network "
                    "itself cannot represent this machine, and no candidate predicts held-out data better; a "
                    "different network (more nodes or paths between them) is what the data asks for. ")
        return (head + "The calibrated model's drift error on the final, unseen block: "
                + "; ".join(f"{c} {before[c]:.2f} µm" for c in before) + "." + outside)
    parts = []
    for f in d.findings:
        sure = "high" if f["confidence"] >= 0.8 else "moderate" if f["confidence"] >= 0.5 else "low"
        where = f["where"][0] if f["where"] else None
        at = (f", most visible on {where['channel']} between {where['start_s'] / 3600:.1f} h and "
              f"{where['end_s'] / 3600:.1f} h") if where else ""
        parts.append(f"{f['mechanism'].replace('_', ' ')} ({_what(f['mechanism'])}; {sure} confidence, "
                     f"{f['confidence']:.0%} of block-bootstrap resamples{at})")
    unsure = [r for r in d.rejected if r["reason"].startswith("not identifiable")]
    text = ("The calibrated model leaves out " + "; then ".join(parts) + ". "
            f"Adding {'it' if len(parts) == 1 else 'them'} changes the drift error on the final block that no step "
            f"of the search saw: {drift}.")
    worse = [c for c in before if after[c] > before[c]]
    if worse:
        text += (f" It is worse there on {len(worse)} of {len(before)} drift channels: the finding fits the data it "
                 "was found on but does not carry over to the final block, so confirm it with "
                 f"{_mechanism(d.findings[0]['mechanism']).experiment_text()} "
                 "before compensating with it.")
    text += outside
    structural = _structural(d)
    if structural:
        text += (" Besides the findings, the baseline's misfit is structural, beyond noise before any mechanism ("
                 + structural + "): what the findings do not explain of it no mechanism in the library does.")
    if unsure:
        text += " " + " ".join(f"{r['mechanism'].replace('_', ' ')} would explain it as well ({r['reason']})."
                               for r in unsure)
    return text


def write(d, out: str | Path, command: str = "") -> dict[str, Any]:
    """Write report.json, report.md, residuals.csv and the figures into ``out``; returns the JSON dict."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    doc = to_json(d)
    (out / "report.json").write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    d.residuals().to_csv(out / "residuals.csv", float_format="%.5g")
    plot_residual_map(d, out / "residual_map.png")
    plot_fit(d, out / "fit.png")
    (out / "report.md").write_text(markdown(d, doc, command), encoding="utf-8")
    return doc


def markdown(d, doc: dict[str, Any], command: str) -> str:
    lines = ["# Missing-physics diagnosis", ""]
    if command:
        lines += ["```", command, "```", ""]
    lines += ["## Verdict", "", doc["verdict"], "",
              f"Baseline network `{d.baseline_network.name}`; {d.screened} candidates (mechanism × place × shape) "
              f"screened; final block from {d.time_s[~d.fit_rows][0] / 3600:.2f} h to {d.time_s[-1] / 3600:.2f} h "
              f"kept out of screening, selection and fitting; {d.seconds:.0f} s.", "",
              "## Drift error (RMSE, µm)", "", "| channel | baseline fit | baseline held-out | augmented fit | "
              "augmented held-out |", "|---|---:|---:|---:|---:|"]
    for c in doc["baseline"]["rmse_um"]:
        lines.append(f"| {c} | {doc['baseline']['rmse_um'][c]:.3f} | {doc['baseline']['heldout_rmse_um'][c]:.3f} | "
                     f"{doc['augmented']['rmse_um'][c]:.3f} | {doc['augmented']['heldout_rmse_um'][c]:.3f} |")
    a = doc.get("adequacy") or {}
    if a.get("channels"):
        lines += ["", "## Baseline adequacy", "", "Before mechanisms compete: the baseline's drift misfit against the "
                  "probe noise, its residual's autocorrelation (sum of the AR coefficients of the noise model the "
                  "tests use; near 1: slow, structural misfit) and its error on the inner validation block (linear "
                  "map refitted without it) against its fitted error.", "",
                  "| channel | fitted RMSE (µm) | noise (µm) | misfit / noise | validation RMSE (µm) | "
                  "validation / fitted | residual AR sum |", "|---|---:|---:|---:|---:|---:|---:|"]
        for c, v in a["channels"].items():
            lines.append(f"| {c} | {v['rmse_um']:.3g} | {v['noise_um']:.3g} | {v['misfit_over_noise']:.3g} | "
                         f"{v['validation_rmse_um']:.3g} | {v['validation_over_fitted']} | "
                         f"{v['residual_ar_sum']:.3g} |")
        if a.get("hidden_nodes"):
            lines += ["", "Hidden nodes of the auto network, chosen on the inner validation block (balanced "
                      "noise-weighted mean squared error): " + "; ".join(
                          f"{h['hidden_nodes']} (start τ {', '.join(f'{x:g}' for x in h['time_constants_h'])} h): "
                          f"fitted {h['fitted_error']:.4g}, held out {h['heldout_error']:.4g}"
                          + (" (chosen)" if h.get("chosen") else "")
                          for h in a["hidden_nodes"]) + "."]
        if a.get("expansion_lags"):
            lines += ["", "Expansion map: every temperature node also read through a first-order lag, kept when it "
                      "cuts the drift error (noise-weighted mean square) on the inner validation block and on the "
                      "inner condition blocks left out in turn: " + "; ".join(
                          (f"lag {', '.join(f'{x:g}' for x in h['lags_h'])} h" if h["lags_h"] else "no lag")
                          + f": held out {h['heldout_drift_error']:.4g}, blocks {h['blocks_drift_error']:.4g}"
                          + (" (chosen)" if h.get("chosen") else "") for h in a["expansion_lags"]) + "."]
    lines += ["", "## Findings", ""]
    if not d.findings:
        lines.append("None.")
    for f in d.findings:
        lines += [f"### {f.get('label', f['mechanism'])} (confidence {f['confidence']:.2f})", "",
                  f"Test: {f['test']}; statistic {f['statistic']:.4g} ({f['dof']} "
                  f"{'degrees of freedom' if f.get('route', '').startswith('decisive') else 'parameters'}), "
                  f"p = {f['p_value']:.2g}; "
                  f"false-discovery level {f['fdr_level']:g}.", "", f["evidence"], "",
                  "| parameter | fitted value | interval |", "|---|---:|---|"]
        for k, v in f["parameters"].items():
            ci = f["ci"][k]
            lines.append(f"| {k} | {v:.4g} | [{ci[0]:.4g}, {ci[1]:.4g}] |")
        for k, v in f["fixed"].items():
            lines.append(f"| {k} | {v:.4g} (held: not identifiable) | — |")
        lines += ["", "Where: " + "; ".join(f"{w['channel']} in {name}" for w, name in zip(f["where"], f["_windows"]))
                  if f["where"] else "Where: spread over the whole recording.", ""]
    lines += ["## Candidates fitted by re-simulation", "",
              "Each candidate is judged on the channels it reaches: the drift channels when its response reaches "
              "them, else the temperature channels it changes. Shares: of the baseline's (balanced, whitened) "
              "misfit explained by the linearised screening and by the re-simulated fit; LR: drop of the whitened "
              "sum of squares on the judged channels (noise model from the baseline's own residual); discovery: "
              "Benjamini–Hochberg at the round's false-discovery level; blocks: share of condition blocks the "
              "linearised screening predicts better when left out, and the t statistic of their gains; "
              "validation: drop of the noise-weighted sum of squares of the judged channels on the inner "
              "validation block, fitted without it, per sample, against the block-to-block spread of the error "
              "the candidate leaves there (its standard error; the gain must exceed it), and the same drop on "
              "the other channels (the guard).", "",
              "| round | candidate | judged on | screening share | fitted share | LR | p | discovery (level) | "
              "blocks improved (t) | validation per sample / spread | other channels | accepted |",
              "|---:|---|---|---:|---:|---:|---:|---|---:|---:|---:|---|"]
    lines += [f"| {t['round']} | {t['candidate']} | {t['judged_on']} | {t['screen_share']:.1%} | "
              f"{t['fit_share']:.1%} | {t['judged_statistic']:.3g} | {t['judged_p_value']:.2g} | "
              f"{'yes' if t['discovered'] else 'no'} ({t['level']:g}) | {t['judged_cv_wins']:.0%} "
              f"({t['judged_cv_t']:.2f}) | {t['judged_validation_gain'] / max(t['validation_samples'], 1):.3g} / "
              f"{t['judged_block_spread']:.3g} | {t['guard_validation_gain']:.3g} | "
              f"{'yes' if t['passed'] else 'no'} |" for t in d.trace]
    lines += ["", "## Rejected", "", "| mechanism | reason |", "|---|---|"]
    lines += [f"| {r['mechanism']} | {r['reason']} |" for r in doc["rejected"]]
    lines += ["", "Files: `report.json`, `residuals.csv` (measured − prediction per channel), `residual_map.png`, "
              "`fit.png`.", ""]
    return "\n".join(lines)


def _bins(d, values: np.ndarray, width_s: float = 1800.0) -> tuple[np.ndarray, np.ndarray]:
    edges = np.arange(d.time_s[0], d.time_s[-1] + width_s, width_s)
    idx = np.clip(np.searchsorted(edges, d.time_s, side="right") - 1, 0, len(edges) - 2)
    counts = np.maximum(np.bincount(idx, minlength=len(edges) - 1), 1)
    grid = np.stack([np.sqrt(np.bincount(idx, v ** 2, minlength=len(edges) - 1) / counts) for v in values.T])
    return edges, grid


def plot_residual_map(d, path: Path) -> Path:
    """RMS residual per channel and 30-min bin, in units of the channel's own baseline RMS, before and after."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    before, after = d.measured - d.baseline, d.measured - d.augmented
    scale = np.maximum(rms(before, axis=0), 1e-12)
    edges, g0 = _bins(d, before / scale)
    _, g1 = _bins(d, after / scale)
    vmax = float(max(g0.max(), 1e-9))
    tall = max(2, len(d.channels) / 3)
    fig, axes = plt.subplots(3, 1, figsize=(12, 2 + 0.5 * len(d.channels)), sharex=True,
                             gridspec_kw={"height_ratios": [1, tall, tall]})
    axes[0].plot(d.time_s / 3600, d.speed_rpm, color="k", lw=0.8)
    axes[0].set_ylabel("rpm")
    cut = d.time_s[~d.fit_rows][0] / 3600 if (~d.fit_rows).any() else None
    for ax, grid, title in ((axes[1], g0, "baseline"), (axes[2], g1, "with the findings")):
        mesh = ax.pcolormesh(edges / 3600, np.arange(len(d.channels) + 1), grid, cmap="magma_r", vmin=0, vmax=vmax)
        ax.set_yticks(np.arange(len(d.channels)) + 0.5, d.channels, fontsize=6)
        ax.invert_yaxis()
        ax.set_title(f"residual RMS / baseline RMS per channel: {title}", fontsize=9)
        if cut is not None:
            ax.axvline(cut, color="tab:blue", lw=1.2, ls="--")
    fig.colorbar(mesh, ax=list(axes), label="relative residual")
    axes[-1].set_xlabel("time (h); dashed: start of the held-out final block")
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)
    return path


def plot_fit(d, path: Path) -> Path:
    """Each displacement channel: measured, baseline and augmented prediction."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    disp = [j for j, k in enumerate(d.kinds) if k == "displacement"]
    fig, axes = plt.subplots(len(disp), 1, figsize=(11, 2.2 * len(disp) + 0.6), sharex=True, squeeze=False)
    h = d.time_s / 3600
    final = ~d.fit_rows
    for ax, j in zip(axes[:, 0], disp):
        c = d.channels[j]
        rb = rmse(d.measured[final, j], d.baseline[final, j])
        ra = rmse(d.measured[final, j], d.augmented[final, j])
        ax.plot(h, d.measured[:, j], color="k", lw=0.7, label="measured")
        ax.plot(h, d.baseline[:, j], color="tab:blue", lw=0.8, ls="--", label=f"baseline (held-out RMSE {rb:.3g} µm)")
        ax.plot(h, d.augmented[:, j], color="tab:red", lw=0.9, label=f"with findings (held-out RMSE {ra:.3g} µm)")
        if final.any():
            ax.axvspan(h[final][0], h[-1], color="0.9", zorder=0)
        ax.set_ylabel(f"{c} (µm)", fontsize=8)
        ax.legend(fontsize=7, loc="upper left", ncol=3, frameon=False)
    axes[-1, 0].set_xlabel("time (h); grey: held-out final block")
    fig.tight_layout()
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)
    return path
