"""Every mechanism's standing in a diagnosis: tested, nested in the baseline, or untestable, with the reason.

The report lists each registered mechanism once (``report.json`` → ``adequacy.mechanisms``), so a user reads
what the diagnosis could not look at, not only what it turned down:

- ``tested``: screened against the baseline's residual (found, or turned down with the test's reason);
- ``nested``: acting anywhere would only duplicate what the baseline already has (a conductance in parallel
  with one the calibration fits, a driver path the simulation already has): not told apart from the baseline;
- ``untestable``: a driver is missing or constant, the network has no place for it, or it declares no form
  for this mode.

The against-simulation finder writes its own list (:mod:`.against_simulation`); :func:`listing` derives the
same from an ``auto`` or spec diagnosis's findings and reasons.
"""

from __future__ import annotations

from typing import Any

NESTED = ("nested",)
UNTESTABLE = ("skipped", "untestable")


def of_reason(reason: str) -> str:
    """The standing a reason in ``rejected`` states."""
    head = reason.strip().lower()
    if head.startswith(NESTED):
        return "nested"
    if head.startswith(UNTESTABLE):
        return "untestable"
    return "tested"


def listing(d, names: list[str]) -> list[dict[str, Any]]:
    """Each mechanism of ``names`` with its standing in diagnosis ``d`` and the reason (found ones: tested)."""
    found = {f["mechanism"] for f in d.findings}
    reasons = {r["mechanism"]: r["reason"] for r in d.rejected}
    out = []
    for mid in names:
        if mid in found:
            out.append({"mechanism": mid, "status": "tested", "reason": "found"})
        elif mid in reasons:
            out.append({"mechanism": mid, "status": of_reason(reasons[mid]), "reason": reasons[mid]})
    return out
