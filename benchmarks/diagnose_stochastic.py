"""The stochastic mode of ``diagnose`` (``thermodrift diagnose TABLE --manifest M --stochastic``) on an independent
generator's recording, beside the output-error mode: used by ``bench_diagnose.py --stochastic``.

:func:`run_stochastic` reads the recording the way the command does (table + manifest, the ``auto`` baseline) and
runs :func:`thermodrift.core.physics.stochastic.machine.select_mechanisms` at its defaults (α 0.01 Bonferroni over
the candidates of a round, three rounds at most); it returns the ``st_*`` fields of a benchmark row. :func:`report`
prints the two modes side by side per case and in a summary (top-1 over hidden cases, nulls with a finding).
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

BELOW_TOL = 0.5  # log-likelihood: a candidate fit ending further below its parent than this is a search failure


def run_stochastic(table: Path, manifest: Path, hidden: str | None, seed: int) -> dict:
    """The stochastic mode on one written recording; ``hidden``: the planted mechanism (None on a null).
    Returns ``st_top1`` (the first finding or "none"), ``st_found``, ``st_verdict``, ``st_seconds`` (s, wall),
    ``st_why_not_hidden`` (the report's reason for the hidden mechanism), ``st_path`` (the selection path),
    ``st_below`` (how far the worst candidate fit ended below the model it extends, log-likelihood; 0 if none did;
    of the candidates that reach their parent where switched off: the others, e.g. the slow structural mode whose
    conductance is fixed, cannot) and ``st_nested`` (mechanisms reported nested)."""
    from thermodrift.core.physics.stochastic.machine import select_mechanisms
    from thermodrift.core.recording import load_recording

    rec = load_recording(table, manifest, require=())
    start = time.perf_counter()
    doc = select_mechanisms(rec, seed=seed)
    seconds = time.perf_counter() - start
    found = [f["mechanism"] for f in doc["findings"]]
    why = next((x["reason"] for x in doc["rejected"] if x["mechanism"] == hidden), "") if hidden else ""
    path = [{k: (round(v, 4) if isinstance(v, float) else v) for k, v in s.items()} for s in doc["selection_path"]]
    cands = [(s["parent_loglik"], c) for s in doc["selection_path"][1:] for c in s["candidates"]]
    below = [p - c["loglik"] for p, c in cands if c["off_loglik"] >= p - BELOW_TOL]  # those it can switch off
    nested = sum(x["reason"].startswith("nested") for x in doc["rejected"])
    return {"st_top1": found[0] if found else "none", "st_found": found, "st_verdict": doc["verdict"],
            "st_seconds": seconds, "st_why_not_hidden": why, "st_path": path,
            "st_below": max([0.0, *below]), "st_nested": nested}


def report(rows: list[dict]) -> str:
    """Output-error and stochastic mode side by side: a summary, then one line per case (rows without the
    stochastic fields are left out)."""
    rows = [r for r in rows if "st_top1" in r]
    if not rows:
        return ""
    hidden = [r for r in rows if r["hidden"] != "none"]
    nulls = [r for r in rows if r["hidden"] == "none"]

    def pair(n: int, d: int) -> str:
        return f"{n}/{d}" + (f" = {n / d:.0%}" if d else "")

    oe_s, st_s = [r["seconds"] for r in rows], [r["st_seconds"] for r in rows]
    out = ["## Output-error and stochastic mode, side by side", "",
           "| metric | output error | stochastic |", "|---|---:|---:|",
           f"| top-1 accuracy, hidden cases | {pair(sum(r['top1'] == r['hidden'] for r in hidden), len(hidden))} | "
           f"{pair(sum(r['st_top1'] == r['hidden'] for r in hidden), len(hidden))} |",
           f"| hidden named anywhere among the findings | "
           f"{pair(sum(r['hidden'] in r['found'] for r in hidden), len(hidden))} | "
           f"{pair(sum(r['hidden'] in r['st_found'] for r in hidden), len(hidden))} |",
           f"| hidden cases with no finding | {sum(r['top1'] == 'none' for r in hidden)}/{len(hidden)} | "
           f"{sum(r['st_top1'] == 'none' for r in hidden)}/{len(hidden)} |",
           f"| null cases with a finding | {sum(r['findings'] > 0 for r in nulls)}/{len(nulls)} | "
           f"{sum(bool(r['st_found']) for r in nulls)}/{len(nulls)} |",
           f"| stochastic: cases with a candidate fit > {BELOW_TOL} below its parent (log-likelihood) | | "
           f"{sum(r.get('st_below', 0.0) > BELOW_TOL for r in rows)}/{sum('st_below' in r for r in rows)} |",
           f"| run time per case, median / max (s, loaded machine) | {statistics.median(oe_s):.0f} / "
           f"{max(oe_s):.0f} | {statistics.median(st_s):.0f} / {max(st_s):.0f} |", "",
           "| case | hidden | output error: top-1 | findings | stochastic: top-1 | findings | stochastic: why the "
           "hidden one was not named | s (oe / st) |", "|---|---|---|---|---|---|---|---:|"]
    for r in rows:
        why = "" if r["st_top1"] == r["hidden"] else r["st_why_not_hidden"][:100]
        out.append(f"| {r['case']} | {r['hidden']} | {r['top1']} | {', '.join(r['found']) or 'none'} | "
                   f"{r['st_top1']} | {', '.join(r['st_found']) or 'none'} | {why} | "
                   f"{r['seconds']:.0f} / {r['st_seconds']:.0f} |")
    return "\n".join(out) + "\n"
