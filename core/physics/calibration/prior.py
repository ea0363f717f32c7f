"""A Gaussian prior on the auto network's nonlinear parameters, its strength chosen on a held-out block.

On a real recording some directions of the auto network (above all the heat exponent p with the conductances)
are flat: the training fit barely changes along them, so without a prior the end point depends on where the
search starts, and so does every extrapolation. The prior pulls each nonlinear parameter towards the auto
network's physically derived start (step-response time constants and heats, p = 1.5), never towards a
jittered start: residual rows √(λ·n)·(θ − θ_start)/scale are appended to the n weighted data residuals, with θ
the search coordinate (log for log parameters, :data:`LOG_SCALE` per unit) and λ the strength per data row,
so λ means the same on a short and a long recording.

λ is chosen on data the fit does not see (:func:`choose_strength`): the recording is cut chronologically at the
start of the running speed block nearest :data:`VALIDATION_FROM` of its duration; each λ of
:data:`STRENGTH_GRID` calibrates on the part before, and the one whose network (continued over the whole
recording, with the linear map solved before the cut) predicts the block after best in the objective's own
weighted residual wins. A recording without two running blocks has no such block and gets no prior.

The intervals (:mod:`.uncertainty`) stay those of the data alone (the Jacobian of the data residuals), so they
still say which parameters the data cannot identify; the prior only decides where the search ends along them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from thermodrift.core.physics.calibration.objective import Problem
from thermodrift.core.recording import speed_segments

LOG_SCALE = 1.0            # prior σ of a log parameter at λ = 1 per data row: a factor e
# λ per data row tried on the held-out block: 0 is no prior; at 10 a log parameter moves ~0.1 % from its start,
# so the top of the grid is the start held fixed and a stronger prior could change nothing
STRENGTH_GRID = (0.0, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0)
VALIDATION_FROM = 2 / 3    # the held-out block starts at the running block nearest this share of the duration


@dataclass
class Prior:
    """Gaussian prior N(centre, (scale/√(λ·rows))²) on the search coordinates, as extra residual rows."""

    names: list[str]       # free parameters, in search order
    centre: np.ndarray     # search coordinates of the auto network's start
    scale: np.ndarray      # σ per search coordinate at λ = 1 per data row
    strength: float        # λ per data row
    rows: int              # data residual rows it is weighed against
    validation: dict[str, Any] = field(default_factory=dict)  # how λ was chosen ({"given": True}: passed in)

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        return math.sqrt(self.strength * self.rows) * (np.asarray(theta) - self.centre) / self.scale

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "gaussian, centred on the auto network's start, in search coordinates (log for log "
                        "parameters)",
                "strength_per_row": self.strength, "data_rows": self.rows,
                "sigma": {n: float(s / math.sqrt(self.strength * self.rows)) if self.strength > 0 else None
                          for n, s in zip(self.names, self.scale)},
                "centre": {n: float(c) for n, c in zip(self.names, self.centre)},
                "validation": self.validation}


def prior_scale(problem: Problem) -> np.ndarray:
    """σ per search coordinate at λ = 1: :data:`LOG_SCALE` for log parameters, the start value's size else."""
    return np.array([LOG_SCALE if p.log else max(abs(p.value), 1.0) for p in problem.free])


def validation_cut(time_s: np.ndarray, speed_rpm: np.ndarray) -> int | None:
    """First sample of the held-out block: the start of the running speed block nearest :data:`VALIDATION_FROM`
    of the duration, with a running block before it; None when there is no such block."""
    t = np.asarray(time_s, dtype=float)
    running = [a for a, _, level in speed_segments(t, speed_rpm) if level > 0]
    if len(running) < 2:
        return None
    target = t[0] + VALIDATION_FROM * (t[-1] - t[0])
    return min(running[1:], key=lambda a: abs(t[a] - target))


def choose_strength(problem: Problem, recording, theta0: np.ndarray,
                    search: Callable[[Callable, np.ndarray], np.ndarray]) -> tuple[float, dict[str, Any]]:
    """(λ per data row, how it was chosen): the strength whose fit predicts the held-out block best (see the
    module docstring). ``problem``: the calibration of the whole ``recording``; ``search(fun, x0)`` returns the
    least-squares optimum of ``fun`` from ``x0`` (the calibration's own search, within its bounds)."""
    names, scale = [p.name for p in problem.free], prior_scale(problem)
    speed = problem.scenario.frame["speed_rpm"].to_numpy()
    cut = validation_cut(problem.time_s, speed)
    if cut is None:
        return 0.0, {"held_out_s": None, "reason": "fewer than two running speed blocks", "evaluations": 0}
    inner = Problem(problem.network, [*problem.free, *problem.projected.values()],
                    recording.select(np.arange(cut)), [s.name for s in problem.disp_sensors],
                    problem.time_constants_s, problem.max_fit_samples, problem.ambient_degC, problem.min_ridge)
    inner.choose_ridge(theta0)
    inner.set_weights(theta0)
    held = problem.rows >= cut
    n_rows = len(inner.rows) * len(inner.channels)
    losses = []
    for strength in STRENGTH_GRID:
        prior = Prior(names, theta0, scale, strength, n_rows)
        theta = search(lambda th: np.concatenate([inner.residuals(th), prior.residuals(th)]), theta0)
        linear = inner.outputs(inner.simulate(theta))["linear"]
        preds = problem.outputs(problem.simulate(theta), linear)["predictions"]
        r = np.concatenate([(c.measured[problem.rows][held] - preds[c.name][held]) / w.weight
                            for c, w in zip(problem.channels, inner.channels)])
        losses.append(float(r @ r) / len(r))
    t = problem.time_s
    return STRENGTH_GRID[int(np.argmin(losses))], {
        "fit_s": [float(t[0]), float(t[cut - 1])], "held_out_s": [float(t[cut]), float(t[-1])],
        "loss_per_row": dict(zip(map(str, STRENGTH_GRID), losses)), "evaluations": inner.evaluations}
