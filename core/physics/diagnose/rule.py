"""The acceptance rule: a fitted candidate is judged on the channels the user cares about, against the scale of
the structural misfit on this machine.

A mechanism whose response reaches the drift channels is judged on them (the quantity a compensation
predicts); the temperature channels only guard against a fit that buys its drift gain by making them worse. A
mechanism that changes the temperature readings alone (a sensor's lag) is judged on the channels it changes, and
the others guard. Judging the temperature and drift channels balanced lets the temperature channels' structural
misfit (surface sensors of a body that is no lumped network) outvote the drift: a true mechanism improving the
unseen drift by half lost on the total, and a sensor lag improving the temperatures alone won.

On the judged channels (:func:`judge`):

* test     the drop of the AR-whitened sum of squares on the fitted rows is a likelihood-ratio statistic,
           χ²(free parameters) with nothing missing; the parameters were fitted on every channel, so on a subset
           the drop is at most what fitting that subset alone would give: the test stays valid (conservative).
           The p-values of a round go to Benjamini–Hochberg (:mod:`.noise`).
* blocks   the condition-blocked cross-validated gain of the screening improves at least half the blocks and
           its per-block mean is positive by a one-sided t-test at :data:`CV_LEVEL` (consistent over the
           conditions, not carried by one block where the baseline extrapolates badly).
* held out fitted without the inner validation block, it predicts that block better by more per sample than
           the error it leaves on those channels varies from block to block (its standard error over the
           condition blocks, the structural misfit's own scale: :data:`SPREAD_Z` of them).
* guard    the other channels on that block are not worse than :data:`GUARD_SHARE` of the baseline's error
           there or :data:`GUARD_Z` standard errors of their own block-to-block spread.

A candidate passes with all three lines of evidence (test, blocks, held out) and the guard, or with the blocks
and the guard when the held-out gain is decisive: in standard errors of the block spread, read as a t statistic
over the condition blocks, significant at the round's level over the fitted candidates (Bonferroni,
:func:`passes`). The whitening removes a slow mechanism's signature from the likelihood ratio (a slow structural
mode whose fit predicts the unseen block nine-tenths better fails it); the held-out block and the blocks then
carry the evidence, both out of sample. A decisive held-out gain never stands in for the blocks: on a machine
the baseline cannot represent, a candidate that soaks up structural misfit on the one held-out block reaches t
of 8–16 while its blocks do not improve consistently.

Structural misfit raises the bar (``structural`` in :func:`passes`): when the baseline misses the inner validation
block's drift by more than :data:`.adequacy.HELD_OUT_RATIO` noise σ (RMS, measured before any mechanism is
tested, :func:`.adequacy.heldout_misfit`), any flexible term soaks up part of that misfit and every test above
becomes a proxy (on machines the baseline cannot represent, a centrifugal step passed all of them on a quarter of
the null recordings). There a candidate is named only when its evidence is decisive: besides the tests above,
fitted without the validation block it leaves no more than :data:`.adequacy.HELD_OUT_RATIO` σ (RMS) there on its
judged channels, and it removes at least :data:`EXCESS_SHARE` of the baseline's mean square there above the noise's
(:meth:`Judged.accounts`). A mechanism that is what is missing accounts for the misfit (the main part of it); a
proxy shaves part of it and leaves it structural. Otherwise the report says it cannot tell, with that reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from thermodrift.core.physics.diagnose.adequacy import HELD_OUT_RATIO
from thermodrift.core.physics.diagnose.screening import cv_of

SPREAD_Z = 1.0     # held-out gain per sample over this many standard errors of the block-to-block spread
GUARD_SHARE = 0.10  # the guarding channels may get this much worse on the held-out block (share of their error) ...
GUARD_Z = 2.0       # ... or this many standard errors of their block spread, whichever is larger
MIN_WINS = 0.5      # share of condition blocks the cross-validated gain must improve
CV_LEVEL = 0.10     # one-sided level of the t-test that the per-block cross-validated gain is positive
EXCESS_SHARE = 0.5  # on a structurally misfit baseline: the share of its held-out excess over noise to remove


@dataclass
class Judged:
    """A fitted candidate's statistics on its judged channels (``group``: "drift" or "temperatures")."""

    group: str
    statistic: float      # drop of the whitened sum of squares on the fitted rows (judged channels)
    p_value: float
    cv_gain: float
    cv_wins: float
    cv_t: float           # t statistic of the per-block cross-validated gains (mean over its standard error)
    val_gain: float       # drop of the noise-weighted sum of squares on the inner validation block (judged)
    val_base: float       # the baseline's sum there
    spread: float         # standard error of the held-out block error per sample (judged channels)
    guard_gain: float     # the same drop on the guarding channels
    guard_base: float
    guard_spread: float
    n_val: int
    channels: np.ndarray = field(default=None, repr=False)  # the judged channels (bool per channel)
    blocks: int = 0       # condition blocks of the cross-validation

    def held_out_t(self) -> float:
        """The held-out gain per sample over the standard error of the block spread."""
        per = self.val_gain / max(self.n_val, 1)
        return per / self.spread if self.spread > 0 else (np.inf if per > 0 else 0.0)

    def held_out_p(self) -> float:
        """One-sided p-value of :meth:`held_out_t` as a t statistic with (condition blocks − 1) degrees of
        freedom."""
        if self.val_gain <= 0:
            return 1.0
        return float(stats.t.sf(self.held_out_t(), max(self.blocks - 1, 1)))

    def three_lines(self, discovered: bool) -> bool:
        """The test, the blocks and the held-out gain all hold (the guard aside)."""
        return discovered and self.consistent() and self.held_out()

    def consistent(self) -> bool:
        return (self.cv_gain > 0 and self.cv_wins >= MIN_WINS
                and self.cv_t >= float(stats.t.isf(CV_LEVEL, max(self.blocks - 1, 1))))

    def held_out(self) -> bool:
        return self.val_gain > 0 and self.val_gain > SPREAD_Z * self.spread * max(self.n_val, 1)

    def left_rms(self) -> float:
        """RMS (noise σ) of the error the candidate leaves on the inner validation block on its judged channels,
        fitted without that block."""
        n = max(self.n_val, 1) * max(int(np.sum(self.channels)) if self.channels is not None else 1, 1)
        return float(np.sqrt(max(self.val_base - self.val_gain, 0.0) / n))

    def accounts(self) -> bool:
        """It accounts for a structural misfit: what it leaves held out is within :data:`HELD_OUT_RATIO` σ (RMS),
        and it removes at least :data:`EXCESS_SHARE` of the baseline's mean square there above the noise's."""
        n = max(self.n_val, 1) * max(int(np.sum(self.channels)) if self.channels is not None else 1, 1)
        excess = self.val_base / n - 1.0
        return (self.val_gain > 0 and self.left_rms() <= HELD_OUT_RATIO
                and self.val_gain / n >= EXCESS_SHARE * excess)

    def guarded(self) -> bool:
        slack = max(GUARD_SHARE * self.guard_base, GUARD_Z * self.guard_spread * max(self.n_val, 1))
        return not self.guard_gain < -slack

    def as_dict(self) -> dict:
        return {"judged_on": self.group, "judged_statistic": self.statistic, "judged_p_value": self.p_value,
                "judged_cv_gain": self.cv_gain, "judged_cv_wins": self.cv_wins,
                "judged_cv_t": self.cv_t, "judged_validation_gain":
                self.val_gain, "judged_validation_base": self.val_base, "judged_block_spread": self.spread,
                "guard_validation_gain": self.guard_gain, "guard_validation_base": self.guard_base,
                "guard_block_spread": self.guard_spread, "validation_samples": self.n_val,
                "cv_blocks": self.blocks, "held_out_p_value": self.held_out_p(), "left_rms": self.left_rms()}


def block_spread(measured: np.ndarray, readings: np.ndarray, sigma: np.ndarray, weights: np.ndarray,
                 rows: np.ndarray, blocks: np.ndarray, val_rows: np.ndarray) -> float:
    """Standard error of a model's mean weighted squared error (noise units, per sample) over one held-out block
    as large as the validation block: the standard deviation of its per-block means over the condition blocks
    of the screening rows, over √(blocks in the validation block). ``weights`` per channel (0: left out)."""
    sq = (((measured - readings) / sigma)[rows]) ** 2 @ weights
    nb = int(blocks.max()) + 1
    counts = np.bincount(blocks, minlength=nb)
    means = np.bincount(blocks, sq, minlength=nb)[counts > 0] / counts[counts > 0]
    k = max(len(np.unique(blocks[np.isin(rows, val_rows)])), 1)
    return float(np.std(means, ddof=1)) / float(np.sqrt(k)) if len(means) > 1 else 0.0


def judged_channels(response: np.ndarray, displacement: np.ndarray) -> np.ndarray:
    """The channels (bool per channel) a candidate with screening ``response`` (rows × channels) is judged on:
    the drift channels (``displacement``) when its response reaches one of them, else the temperature channels it
    changes."""
    reach = np.abs(response).max(axis=0) > 1e-9
    return displacement if (reach & displacement).any() else (~displacement & reach)


def judge(f, displacement: np.ndarray, group_is_drift: np.ndarray, measured: np.ndarray, sigma: np.ndarray,
          rows: np.ndarray, blocks: np.ndarray, val_rows: np.ndarray) -> Judged:
    """The statistics of fitted candidate ``f`` (:class:`.selection.Fitted`) on its judged channels: the drift
    channels (``displacement``, bool per channel) when its response reaches them, else the temperature channels
    its response changes (a lagged sensor's own). ``group_is_drift`` marks the screening's amplitude groups that
    are drift channels."""
    judged = judged_channels(f.candidate.response, displacement)
    drift = bool((judged & displacement).any())
    guard = ~judged
    cv_w = (group_is_drift if drift else ~group_is_drift).astype(float)
    cv_gain, cv_wins = cv_of(cv_w, f.candidate.cv_blocks)
    per_block = f.candidate.cv_blocks @ cv_w
    sd = float(np.std(per_block, ddof=1)) if len(per_block) > 1 else 0.0
    mean = float(np.mean(per_block)) if len(per_block) else 0.0
    cv_t = mean / (sd / float(np.sqrt(len(per_block)))) if sd > 0 else (np.inf if mean > 0 else 0.0)
    stat = float(f.drop[judged].sum())

    def spread(mask):
        return block_spread(measured, f.readings, sigma, mask.astype(float), rows, blocks, val_rows) if mask.any() \
            else 0.0

    return Judged("drift" if drift else "temperatures", stat, float(stats.chi2.sf(max(stat, 0.0), max(f.dof, 1))),
                  cv_gain, cv_wins, cv_t, float(f.val_drop[judged].sum()), float(f.val_base[judged].sum()),
                  spread(judged), float(f.val_drop[guard].sum()), float(f.val_base[guard].sum()), spread(guard),
                  len(val_rows), judged, len(per_block))


def passes(f, j: Judged, discovered: bool, decisive_level: float = 0.0, structural: bool = False) -> bool:
    """The module docstring's rule, given the Benjamini–Hochberg decision ``discovered``, the level at which a
    held-out gain is decisive (the round's level over the number of fitted candidates; 0: never) and whether the
    baseline's held-out misfit is ``structural`` (then the candidate must also account for it)."""
    if not (j.statistic > 0 and not f.outside and j.guarded()):
        return False
    if structural and not j.accounts():
        return False
    if j.three_lines(discovered):
        return True
    return j.held_out_p() < decisive_level and j.consistent()


def why_not(f, j: Judged, discovered: bool, level: float, m: int, structural: float | None = None) -> str:
    """The first test a candidate fails, in words; ``structural``: the baseline's held-out drift misfit (RMS, noise
    σ) when the candidate passes every other test and is withheld only because it does not account for that
    structural misfit (:meth:`Judged.accounts`), else None."""
    where = "drift" if j.group == "drift" else "temperature"
    if structural is not None:
        return (f"cannot tell: the baseline's misfit is structural (held-out drift RMS {structural:.3g} σ, over "
                f"{HELD_OUT_RATIO:g} σ, before any mechanism), and fitted without the inner validation block this "
                f"mechanism still leaves {j.left_rms():.3g} σ (RMS) there on its {where} channels (it must leave "
                f"within {HELD_OUT_RATIO:g} σ and remove {EXCESS_SHARE:.0%} of the excess over noise): it shaves the "
                "misfit, it does not account for it, so the evidence is not decisive")
    if j.statistic <= 0:
        return f"re-simulated fit does not lower the (whitened) misfit of the {where} channels"
    if not discovered:
        return (f"not significant: whitened likelihood ratio {j.statistic:.3g} on the {where} channels, "
                f"p = {j.p_value:.2g}, not a discovery at false-discovery level {level:g} (Benjamini–Hochberg "
                f"over {m} candidates)")
    if f.outside:
        return "fits only with unphysical values: " + "; ".join(f.outside)
    if not j.consistent():
        return (f"held-out condition blocks do not improve consistently on the {where} channels (gain "
                f"{j.cv_gain:.3g}, {j.cv_wins:.0%} of blocks, t = {j.cv_t:.2f} over {j.blocks} blocks)")
    per = j.val_gain / max(j.n_val, 1)
    if j.val_gain > 0 and not j.held_out():
        return (f"fitted without the last part of the fitted data, it predicts that part's {where} channels better "
                f"than the baseline by {per:.3g} per sample (noise units), within {SPREAD_Z:g} × {j.spread:.3g}, by "
                "which the error it leaves varies from block to block: structural misfit, not this mechanism")
    if not j.held_out():
        return (f"fitted without the last part of the fitted data, it does not predict that part's {where} "
                f"channels better than the baseline (noise-weighted gain {j.val_gain:.3g} of {j.val_base:.3g})")
    return (f"it buys its {where} gain on the held-out block by making the other channels worse "
            f"({j.guard_gain:.3g} of {j.guard_base:.3g}, noise-weighted)")
