"""Cross-fitted condition blocks: the blocks test out of sample for a candidate's fitted shape as well as its
amplitudes.

The screening's blocked gain (:mod:`.screening`) solves a candidate's amplitudes without each block, at the
response of its start values. The re-simulated fit (:mod:`.selection`) moves the parameters that shape the response
(an exponent, a viscosity coefficient, a conductance, a time constant) using every block; judging the blocks on the
response at the fitted values lets that shape, fitted on every block, leak into the blocks it is judged on.

Here the condition blocks are split into :data:`GROUPS` contiguous groups. For each group the candidate's searched
parameters are fitted again without it, warm-started at the full fit, by at most :data:`EVALUATIONS` evaluations of
a bounded least-squares search on the screening's own metric (the response re-simulated, whitened and projected
like the residual, its amplitudes solved on the kept blocks; the groups balanced as in the screening's ranking).
Each block of the group is then scored as the screening scores it: the amplitudes solved without the block, on the
response of the parameters fitted without its group. What the candidate fits is never fitted on the block it is
judged on; the baseline's own linear parameters and its noise model, projected out of residual and response alike,
stay solved on every screening row as in the screening. A candidate with no searched parameters (only linear ones)
has nothing to refit: its cross-fitted gains are the screening's.

Contiguous groups, not interleaved ones: neighbouring condition blocks share their thermal state (the temperature
one block leaves is where the next starts), so a shape fitted on a block's neighbours would interpolate it; a left-out
stretch of conditions is predicted forward or backward in time, as the final and inner validation blocks are and as a
compensation is used.

scipy's ``least_squares`` searches; the calibration (:func:`~thermodrift.core.physics.calibration.calibrate`) fits
another objective and cannot leave out rows in the middle of a recording.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import least_squares

from thermodrift.core.errors import InputError
from thermodrift.core.physics.calibration import predict
from thermodrift.core.physics.diagnose import screening
from thermodrift.core.physics.network import Network

GROUPS = 4        # contiguous groups of condition blocks left out in turn (fewer when there are fewer blocks)
EVALUATIONS = 8   # evaluations of each group's refit (warm-started at the full fit; Jacobian evaluations aside)


def group_blocks(n_blocks: int, groups: int = GROUPS) -> list[np.ndarray]:
    """Block ids 0…n_blocks−1 in min(n_blocks, groups) contiguous groups of near-equal size."""
    return [g for g in np.array_split(np.arange(n_blocks), min(n_blocks, groups)) if len(g)]


class _Refit:
    """A fitted candidate's searched parameters on the search scale (:class:`~thermodrift.core.physics.calibration.
    FreeParameter`), and its response on the round's screen at given values."""

    def __init__(self, f, screen: screening.Screen, scenario, channels: list[str]):
        self.f, self.screen, self.scenario, self.channels = f, screen, scenario, channels
        searched = [(fp, f.parameters[fp.name]) for fp, _ in f.declared if fp.scale in ("log", "linear")]
        self.fps = [fp for fp, _ in searched]
        self.free = [fp.on_network_scale(v) for fp, v in searched]
        self.lo = np.array([p.to_search(p.low) for p in self.free])
        self.hi = np.array([p.to_search(p.high) for p in self.free])
        self.theta0 = np.clip([p.to_search(p.value) for p in self.free], self.lo, self.hi)
        self.nonneg = screening._nonneg_first(screen, f.candidate)
        self.group_of = np.zeros(len(screen.resid), dtype=int)
        for g, members in enumerate(screen.groups):
            self.group_of[members] = g
        self.root = np.sqrt(screen.weights[self.group_of])

    def network(self, theta: np.ndarray) -> Network:
        return self.f.network.with_values({path: x for p, v in zip(self.free, theta)
                                           for path, x in p.path_values(p.from_search(float(v))).items()})

    def scored(self, theta: np.ndarray) -> screening.Candidate | None:
        """The candidate scored on the screen with its response at ``theta`` (None: it cannot be simulated)."""
        try:
            raw = predict(self.network(theta), self.scenario)[0][self.channels].to_numpy()
        except InputError:
            return None
        response = raw - self.screen.base.raw
        if not np.isfinite(response).all():
            return None
        cand = dataclasses.replace(self.f.candidate, response=response, parts=[], part_betas=[])
        return screening.score(self.screen, cand, 1)

    def without(self, group: np.ndarray, evaluations: int = EVALUATIONS) -> np.ndarray:
        """The search coordinates fitted without the condition blocks ``group``: the whitened, projected residual
        of the kept rows less the response, its amplitudes solved on the kept blocks."""
        screen = self.screen
        kept = ~np.isin(screen.blocks, group)
        keep_blocks = ~np.isin(np.arange(int(screen.blocks.max()) + 1), group)

        def resid(theta: np.ndarray) -> np.ndarray:
            c = self.scored(theta)
            if c is None:
                return np.full(int(kept.sum()) * len(screen.resid), 1e6)
            beta = screening._beta(c.block_stats[keep_blocks].sum(axis=0), self.nonneg)
            return np.concatenate([(screen.resid[k] - beta[self.group_of[k]] * c.projected[k])[kept] * self.root[k]
                                   for k in range(len(screen.resid))])

        return least_squares(resid, self.theta0, bounds=(self.lo, self.hi), method="trf", max_nfev=evaluations,
                             diff_step=1e-4, x_scale=1.0).x

    def values(self, theta: np.ndarray) -> dict[str, float]:
        """The parameters' values (their own units) at search coordinates ``theta``."""
        return {fp.name: float(fp.from_network(p.from_search(float(v))))
                for fp, p, v in zip(self.fps, self.free, theta)}


def refit_without(f, screen: screening.Screen, scenario, channels: list[str], group: np.ndarray,
                  evaluations: int = EVALUATIONS) -> dict[str, float]:
    """The searched parameters of fitted candidate ``f`` (their own units) fitted without the condition blocks
    ``group`` (ids), warm-started at the full fit."""
    r = _Refit(f, screen, scenario, channels)
    return r.values(r.without(group, evaluations)) if r.free else {}


def block_gains(f, screen: screening.Screen, scenario, channels: list[str], groups: int = GROUPS,
                evaluations: int = EVALUATIONS) -> tuple[np.ndarray, int]:
    """(blocks, amplitude groups): the held-out gain of each condition block of fitted candidate ``f``
    (:class:`.selection.Fitted`) on ``screen`` (the round's screen), its searched parameters fitted without the
    block's contiguous group and its amplitudes without the block; and the number of groups (0: nothing searched,
    the screening's gains)."""
    r = _Refit(f, screen, scenario, channels)
    if not r.free:
        return f.candidate.cv_blocks, 0
    out = np.array(f.candidate.cv_blocks, dtype=float)
    split = group_blocks(int(screen.blocks.max()) + 1, groups)
    for group in split:
        c = r.scored(r.without(group, evaluations))
        out[group] = 0.0 if c is None else c.cv_blocks[group]  # a refit that cannot be simulated gains nothing
    return out, len(split)
