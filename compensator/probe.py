"""Probe updates: a touch probe measures the real drift now and then; a Kalman filter on a random-walk bias per
target corrects the compensator online, without refitting the model.

Model: the error of the model's prediction, e = measured − predicted (µm), is a bias b that drifts as a random
walk, b(t + Δt) = b(t) + w, w ~ N(0, q·Δt); a probe reads e with noise v ~ N(0, r). Between probes the variance
grows by q·Δt; a probe moves b by the gain K = P / (P + r) towards the observed error. Written by hand: it is a
scalar filter of a few lines per target.
"""

from __future__ import annotations

import numpy as np

# Defaults (stated in every package's "probe" section): a probe on an artefact repeats to about 1 µm; the bias of
# a thermal model wanders by a few µm per hour of changing conditions; before the first probe nothing is known.
PROBE_NOISE_UM = 1.0
BIAS_DRIFT_UM_PER_SQRT_H = 5.0
INITIAL_UM = 20.0


class BiasFilter:
    """Per-target bias b (µm) and its variance P (µm²)."""

    def __init__(self, n_targets: int, noise_um: float = PROBE_NOISE_UM,
                 drift_um_per_sqrt_h: float = BIAS_DRIFT_UM_PER_SQRT_H, initial_um: float = INITIAL_UM):
        self.b = np.zeros(n_targets)
        self.P = np.full(n_targets, float(initial_um) ** 2)
        self.r = float(noise_um) ** 2
        self.q = float(drift_um_per_sqrt_h) ** 2 / 3600.0  # µm² per s
        self.t: float | None = None

    def advance(self, t_s: float) -> None:
        """Let the bias variance grow up to time ``t_s`` (s)."""
        if self.t is not None and t_s > self.t:
            self.P += self.q * (t_s - self.t)
        self.t = t_s if self.t is None else max(self.t, t_s)

    def correct(self, target: int, error_um: float) -> float:
        """Fold in one probe of target ``target``: ``error_um`` = measured − predicted; returns the new bias."""
        k = self.P[target] / (self.P[target] + self.r)
        self.b[target] += k * (error_um - self.b[target])
        self.P[target] *= 1.0 - k
        return float(self.b[target])
