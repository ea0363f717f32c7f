"""Screening: every registered mechanism at every place it can act, scored by how well its linearised response
explains the calibrated baseline's residual.

For a candidate (mechanism, place, shape) the response R is the change of every sensor reading when the
mechanism is added to the baseline network at its default (or shape) parameters, by re-simulation. The model
``residual ≈ β_g R`` has one amplitude for all temperature channels and one per displacement channel (their
sensitivities are linear anyway). Both sides are divided by each channel's noise σ and have the baseline's own
linear parameters projected out (offset per temperature channel; sensitivities, tilts, centrifugal term and
offset per displacement channel), so a candidate only scores with what the baseline cannot already absorb.

Scores on the screening rows: ΔSSE in units of each channel's noise variance, which is the likelihood-ratio
statistic of the amplitudes when the noise σ is known (χ² with one degree of freedom per amplitude when
nothing is missing); a balanced ΔSSE for ranking (temperature channels together weigh as much as displacement
channels together); and a condition-blocked cross-validated gain (amplitudes fitted without a block, scored
on it). A mechanism acting at several places
at once (cutting heat into the tool and the spindle) is a greedy union of its best places (:func:`best_compound`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import stats
from scipy.optimize import lsq_linear

from thermodrift.core.errors import InputError
from thermodrift.core.physics.calibration import predict
from thermodrift.core.physics.diagnose.adequacy import is_lag_node
from thermodrift.core.physics.diagnose.noise import NoiseModel
from thermodrift.core.physics.mechanisms import added
from thermodrift.core.physics.network import Network, TemperatureSensor
from thermodrift.core.physics.synthetic import PT100_TOLERANCE

# Relative singular-value cut of the linear refits (offsets, sensitivities): an auto network's many node
# temperatures are nearly collinear, and keeping directions below 1e-6 of the largest made the refitted drift
# extrapolate to the unseen block 2-3 times worse on FL_THERMAL.
LINEAR_RCOND = 1e-6
# Boundary temperatures the network is driven by: each is read by a sensor with an unknown constant offset, so one
# offset per input is solved with the linear parameters (otherwise a mechanism acting on the network's
# temperature-dependent parts scores by absorbing it), bounded by the loosest Pt100 class: a larger one is no
# sensor offset but something the network misses.
BOUNDARY_INPUTS = ("ambient_degC", "coolant_inlet_degC")
BOUNDARY_CLASS = "B"


@dataclass
class Baseline:
    """A network's readings over the recording and what its linear parameters can absorb.

    ``raw`` are the network's own noise-free readings; ``readings`` the same with every channel's linear
    parameters (offset; sensitivities, tilts, centrifugal term and offset) and the boundary inputs' offsets
    (:data:`BOUNDARY_INPUTS`, one each, shared by all channels) solved again by least squares on the fitting
    rows at full resolution, so baseline and augmented networks are compared on equal terms.
    """

    network: Network
    raw: np.ndarray               # (samples, channels)
    readings: np.ndarray          # (samples, channels)
    nuisance: list[np.ndarray]    # per channel: (samples, q) regressors solved linearly


@dataclass
class Candidate:
    mechanism: str
    options: dict[str, Any]
    shape: dict[str, float]
    network: Network
    free: list
    response: np.ndarray          # (samples, channels) readings change at the candidate's start values
    signature: str = ""
    label: str = ""
    factory: Any = None
    # scores (screening rows)
    dsse: float = 0.0
    lr: float = 0.0
    dof: int = 0
    p_value: float = 1.0
    cv_gain: float = 0.0
    cv_wins: float = 0.0
    cv_blocks: Any = None         # (blocks, groups): held-out gain of each block, amplitudes fitted without it
    group_gain: Any = None        # (groups,): gain per amplitude group on the screening rows
    beta: dict[str, float] = field(default_factory=dict)
    dsse_bal: float = 0.0
    block_stats: Any = None       # (blocks, groups, 3): <R,r>, <R,R>, <r,r> per block and group
    projected: Any = None         # per channel, the response projected and weighted like the residual
    gram: Any = None              # (blocks, groups, k+1, k+1) Gram matrices of [responses, residual]
    parts: list = field(default_factory=list)       # single-place candidates of a several-place candidate
    part_betas: list = field(default_factory=list)  # their temperature amplitudes


def baseline_of(network: Network, scenario, channels: list[str], measured: np.ndarray, rows: np.ndarray,
                sigma: np.ndarray) -> Baseline:
    """Readings of ``network`` over ``scenario`` for ``channels``, refitted linearly on ``rows``; ``sigma`` per
    channel (°C, µm) weighs the channels in the shared boundary offsets (:func:`_boundary_offsets`)."""
    readings, X = predict(network, scenario)
    idx = {n: i for i, n in enumerate(network.node_names)}
    n_ref = network.reference_speed_rpm
    ratio2 = (scenario.frame["speed_rpm"].to_numpy() / n_ref) ** 2
    nuisance = []
    for ch in channels:
        sensor = next(s for s in network.sensors if s.name == ch)
        ones = np.ones((len(X), 1))
        if isinstance(sensor, TemperatureSensor):
            nuisance.append(ones)
            continue
        out = network.output(sensor.output)
        cols = [X[:, idx[n]] - X[0, idx[n]] for n in (out.sensitivity_um_K or network.node_names)]
        cols += [(X[:, idx[h]] - X[0, idx[h]]) - (X[:, idx[c]] - X[0, idx[c]]) for h, c, _ in out.tilt_pairs()]
        if out.centrifugal_um:
            cols.append(ratio2)
        nuisance.append(np.column_stack(cols + [ones[:, 0]]))
    raw = readings[channels].to_numpy()
    fitted = raw + _boundary_offsets(network, scenario, channels, measured, rows, sigma, raw, nuisance)
    for c, Z in enumerate(nuisance):
        if Z.shape[1] == 1:  # a temperature channel: its offset
            fitted[:, c] += float(np.mean(measured[rows, c] - fitted[rows, c]))
            continue
        scale = np.maximum(np.abs(Z[rows]).max(axis=0), 1e-12)
        coef = np.linalg.lstsq(Z[rows] / scale, measured[rows, c], rcond=LINEAR_RCOND)[0]
        fitted[:, c] = (Z / scale) @ coef
    return Baseline(network, raw, fitted, nuisance)


def _boundary_offsets(network: Network, scenario, channels: list[str], measured: np.ndarray, rows: np.ndarray,
                      sigma: np.ndarray, raw: np.ndarray, nuisance: list[np.ndarray]) -> np.ndarray:
    """The readings' change (samples, channels) from the constant offsets of the boundary inputs
    (:data:`BOUNDARY_INPUTS`) that best explain ``measured`` on ``rows``: one offset (K) per input, shared by
    every channel, within the Pt100 tolerance of :data:`BOUNDARY_CLASS` at the input's mean temperature, fitted
    by σ-weighted least squares beside each channel's own linear parameters."""
    responses, tolerance = [], []
    base, slope = PT100_TOLERANCE[BOUNDARY_CLASS]
    for col in BOUNDARY_INPUTS:  # the readings' change when the input is 1 K higher throughout
        frame = scenario.frame.copy()
        frame[col] = frame[col] + 1.0
        r = predict(network, type(scenario)(frame, scenario.name))[0][channels].to_numpy() - raw
        if np.abs(r).max() > 1e-9:
            responses.append(r)
            tolerance.append(base + slope * abs(float(scenario.frame[col].mean())))
    if not responses:
        return np.zeros_like(raw)
    k = len(responses)
    lhs, rhs = np.zeros((k, k)), np.zeros(k)
    for c, Z in enumerate(nuisance):
        Q = _basis(Z, rows)
        target = measured[:, c] - (raw[:, c] if Z.shape[1] == 1 else 0.0)  # a displacement's map is re-solved
        A = np.column_stack([_project(Q, rows, r[:, c]) for r in responses]) / sigma[c]
        lhs += A.T @ A
        rhs += A.T @ _project(Q, rows, target) / sigma[c]
    w, V = np.linalg.eigh(lhs)  # ||Aδ − y||² = ||Hδ − H⁻¹Aᵀy||² + const with AᵀA = H²
    half = (V * np.sqrt(np.maximum(w, 1e-12 * max(w.max(), 1e-300)))) @ V.T
    tol = np.array(tolerance)
    delta = lsq_linear(half, np.linalg.solve(half, rhs), bounds=(-tol, tol)).x
    return sum(d * r for d, r in zip(delta, responses))


def candidates(registry, base: Baseline, scenario, channels: list[str], recording,
               only: list[str] | None = None, free_paths: frozenset[str] = frozenset()
               ) -> tuple[list[Candidate], list[dict]]:
    """Every (mechanism, place, shape) that the recording can drive and that changes some reading; and the
    mechanisms rejected with their reason (missing or constant driver, no place in the network, no effect, or
    nested in the baseline at every place: :func:`nested`, given the baseline calibration's free parameter
    paths, a place where it is nested being left out; or no place because acting anywhere would only duplicate
    the baseline, :meth:`~thermodrift.core.physics.mechanisms.Mechanism.unplaced`)."""
    out, rejected = [], []
    for mid in registry.names("mechanism"):
        if only is not None and mid not in only:
            continue
        cls = registry.get("mechanism", mid).factory
        reason = cls.missing_drivers(recording)
        if reason:
            rejected.append({"mechanism": mid, "reason": f"skipped: {reason}"})
            continue
        found, errors, parallel = 0, [], []
        for options in cls.places(base.network):
            if _names_lag_node(base.network, options):  # an expansion map's lagged reading, no part to act on
                continue
            for shape in list(cls.shapes) or [{}]:  # the shapes it declares besides its defaults
                try:
                    mech = cls(**options)
                    net, free = mech.declare(base.network, **shape)
                    twins = nested(base.network, net, free_paths)
                    if twins:  # not simulated: fitting it would only refit the baseline
                        parallel += twins
                        continue
                    readings = predict(net, scenario)[0][channels].to_numpy()
                except InputError as exc:
                    errors.append(str(exc))
                    continue
                response = readings - base.raw
                if not np.isfinite(response).all() or np.abs(response).max() < 1e-9:
                    continue
                place = _place_text(options)
                shape_text = ", ".join(f"{k}={v:g}" for k, v in shape.items())
                out.append(Candidate(mid, options, shape, net, free, response, cls.signature,
                                     f"{mid} at {place}" + (f" ({shape_text})" if shape else ""), cls))
                found += 1
        if not found and parallel:
            twins = ", ".join(dict.fromkeys(parallel))
            rejected.append({"mechanism": mid, "reason": (
                f"nested in the baseline: every conductance it adds runs parallel to one the baseline already fits "
                f"({twins}), so fitting it only refits the baseline; testing it needs a network whose conductances "
                "are known (--network spec.yaml)")})
        elif not found and (why := cls.unplaced(base.network)):
            rejected.append({"mechanism": mid, "reason": why})
        elif not found:
            why = errors[0] if errors else "no place in this network where it changes any reading"
            rejected.append({"mechanism": mid, "reason": f"skipped: {why}"})
    return out, rejected


def nested(base: Network, augmented: Network, free_paths: frozenset[str]) -> list[str]:
    """The baseline edges whose free conductances (paths in ``free_paths``) the edges ``augmented`` adds run
    parallel to, when adding those edges (constant G, the same two ends) is all that ``augmented`` changes; else
    []. Two conductances in parallel sum, so such a mechanism is a change of the baseline's own parameters."""
    if any(getattr(base, f) != getattr(augmented, f) for f in ("nodes", "advections", "sources", "outputs",
                                                               "sensors")):
        return []
    have = {e.name: e for e in base.edges}
    if any(e.name in have and e != have[e.name] for e in augmented.edges):
        return []
    twins = []
    for e in added(base, augmented, "edges"):
        twin = next((b for b in base.edges if {b.a, b.b} == {e.a, e.b} and f"edges.{b.name}.G_W_K" in free_paths),
                    None)
        if twin is None or e.G_rot_W_K:
            return []
        twins.append(twin.name)
    return twins


def _names_lag_node(network, options: dict[str, Any]) -> bool:
    values = [v for x in options.values() for v in (x if isinstance(x, (list, tuple)) else [x])]
    return any(isinstance(v, str) and is_lag_node(network, v) for v in values)


def _basis(Z: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the columns of Z on ``rows`` (numerically dependent columns dropped)."""
    return _basis_of(Z[rows])


def _basis_of(A: np.ndarray) -> np.ndarray:
    A = A / np.maximum(np.abs(A).max(axis=0), 1e-12)
    U, sv, _ = np.linalg.svd(A, full_matrices=False)
    return U[:, sv > LINEAR_RCOND * sv[0]] if len(sv) and sv[0] > 0 else U[:, :0]


def _project(Q: np.ndarray, rows: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """``vec`` on ``rows`` minus its projection on the orthonormal columns Q."""
    v = vec[rows]
    return v - Q @ (Q.T @ v)


@dataclass
class Screen:
    """Projected, weighted residuals of the baseline on the screening rows, grouped for the amplitude model.

    ``weights`` balance the groups for ranking: the temperature channels together count as much as the
    displacement channels together (otherwise 20 temperature channels outvote one drift channel).
    """

    rows: np.ndarray
    blocks: np.ndarray
    groups: list[list[int]]          # channel indices per amplitude group (temperatures; each displacement)
    group_names: list[str]
    resid: list[np.ndarray]          # per channel, projected and weighted
    sse0: float
    sse0_bal: float
    weights: np.ndarray              # per group
    base: Baseline
    sigma: np.ndarray
    bases: list[np.ndarray]          # per channel, orthonormal basis of the whitened linear regressors
    noise: NoiseModel                # AR whitening per channel, from the baseline's own residual

    def transform(self, c: int, vec: np.ndarray) -> np.ndarray:
        """Channel ``c``'s series (all samples, °C or µm) on the screening rows: divided by its noise σ,
        whitened by the baseline's noise model and with the whitened linear regressors projected out."""
        w = self.noise.apply(c, vec[self.rows] / self.sigma[c])
        return w - self.bases[c] @ (self.bases[c].T @ w)

    @property
    def temps_first(self) -> bool:
        return bool(self.group_names) and self.group_names[0] == "temperatures"

    def stack(self, g: int, vectors: list[np.ndarray]) -> np.ndarray:
        return np.concatenate([vectors[c] for c in self.groups[g]])


def prepare(base: Baseline, measured: np.ndarray, sigma: np.ndarray, kinds: list[str], channels: list[str],
            rows: np.ndarray, blocks: np.ndarray, noise: NoiseModel | None = None) -> Screen:
    """The screen of ``base``'s residual on ``rows``; ``noise`` (default: fitted to this residual,
    :mod:`.noise`) whitens residuals and responses alike."""
    plain = [_project(_basis(base.nuisance[c], rows), rows, (measured[:, c] - base.readings[:, c]) / sigma[c])
             for c in range(len(channels))]
    if noise is None:
        noise = NoiseModel(np.column_stack(plain))
    bases = [_basis_of(noise.apply(c, base.nuisance[c][rows])) for c in range(len(channels))]
    resid = []
    for c in range(len(channels)):
        w = noise.apply(c, (measured[rows, c] - base.readings[rows, c]) / sigma[c])
        resid.append(w - bases[c] @ (bases[c].T @ w))
    temps = [i for i, k in enumerate(kinds) if k == "temperature"]
    disps = [i for i, k in enumerate(kinds) if k == "displacement"]
    groups = ([temps] if temps else []) + [[i] for i in disps]
    names = (["temperatures"] if temps else []) + [channels[i] for i in disps]
    share = 0.5 if temps and disps else 1.0
    weights = np.array(([share / len(temps)] if temps else []) + [share / len(disps)] * len(disps))
    sse0 = float(sum(r @ r for r in resid))
    sse0_bal = float(sum(w * sum(resid[c] @ resid[c] for c in m) for w, m in zip(weights, groups)))
    return Screen(rows, blocks, groups, names, resid, sse0, sse0_bal, weights, base, sigma, bases, noise)


def _nonneg_first(screen: Screen, cand: Candidate) -> bool:
    return screen.temps_first and not getattr(cand.factory, "signed", False)


def score(screen: Screen, cand: Candidate, n_tests: int) -> Candidate:
    """Fill the candidate's screening scores (see the module docstring)."""
    nb = int(screen.blocks.max()) + 1
    stats_ = np.zeros((nb, len(screen.groups), 3))
    R = [screen.transform(c, cand.response[:, c]) for c in range(len(screen.resid))]
    cand.projected = R
    for g, members in enumerate(screen.groups):
        for c in members:
            for k, v in enumerate((R[c] * screen.resid[c], R[c] * R[c], screen.resid[c] ** 2)):
                stats_[:, g, k] += np.bincount(screen.blocks, v, minlength=nb)
    cand.block_stats = stats_
    tot = stats_.sum(axis=0)
    beta = _beta(tot, _nonneg_first(screen, cand))
    gain = 2 * beta * tot[:, 0] - beta ** 2 * tot[:, 1]
    cand.beta = {n: float(b) for n, b in zip(screen.group_names, beta)}
    cand.dsse = float(gain.sum())
    cand.dsse_bal = float(screen.weights @ gain)
    cand.dof = max(int((tot[:, 1] > 1e-12).sum()), 1)
    cand.lr = max(cand.dsse, 0.0)
    cand.p_value = float(stats.chi2.sf(cand.lr, cand.dof))
    cand.group_gain = gain
    cand.cv_blocks = np.zeros((nb, len(screen.groups)))
    for b in range(nb):
        bb = _beta(tot - stats_[b], _nonneg_first(screen, cand))
        cand.cv_blocks[b] = 2 * bb * stats_[b, :, 0] - bb ** 2 * stats_[b, :, 1]
    cand.cv_gain, cand.cv_wins = cv_of(screen.weights, cand.cv_blocks)
    return cand


def cv_of(weights: np.ndarray, cv_blocks: np.ndarray) -> tuple[float, float]:
    """Condition-blocked cross-validated gain with the amplitude groups weighted by ``weights`` (0: left out)
    and the share of blocks it improves."""
    per_block = cv_blocks @ weights
    return float(per_block.sum()), float(np.mean(per_block > 0)) if len(per_block) else 0.0


def _beta(tot: np.ndarray, nonneg_first: bool) -> np.ndarray:
    beta = np.where(tot[..., 1] > 1e-12, tot[..., 0] / np.maximum(tot[..., 1], 1e-300), 0.0)
    if nonneg_first:
        beta[..., 0] = np.maximum(beta[..., 0], 0.0)  # a missing heat or conductance cannot enter negatively
    return beta


def _gram(screen: Screen, parts: list[Candidate]) -> np.ndarray:
    """Per block and group the Gram matrix of [responses…, residual]: (blocks, groups, k+1, k+1)."""
    nb = int(screen.blocks.max()) + 1
    k = len(parts)
    out = np.zeros((nb, len(screen.groups), k + 1, k + 1))
    for g in range(len(screen.groups)):
        for c in screen.groups[g]:
            cols = [p.projected[c] for p in parts] + [screen.resid[c]]
            for i in range(k + 1):
                for j in range(i, k + 1):
                    v = np.bincount(screen.blocks, cols[i] * cols[j], minlength=nb)
                    out[:, g, i, j] += v
                    if i != j:
                        out[:, g, j, i] += v
    return out


def _solve(G: np.ndarray, nonneg: bool) -> np.ndarray:
    """Amplitudes minimising ||A β − r||² from the Gram matrix [[AᵀA, Aᵀr], [rᵀA, rᵀr]]."""
    from scipy.optimize import nnls

    k = G.shape[0] - 1
    AtA, Atr = G[:k, :k], G[:k, k]
    if not nonneg:
        return np.linalg.lstsq(AtA, Atr, rcond=1e-12)[0]
    # ||Aβ − r||² = ||Hβ − H⁻¹Aᵀr||² + const with AᵀA = H² (H symmetric): a k×k non-negative problem
    w, V = np.linalg.eigh(AtA)
    w = np.maximum(w, 1e-12 * max(w.max(), 1e-300))
    half = (V * np.sqrt(w)) @ V.T
    return nnls(half, np.linalg.solve(half, Atr))[0]


def _gain(G: np.ndarray, beta: np.ndarray) -> float:
    k = len(beta)
    return float(2 * beta @ G[:k, k] - beta @ G[:k, :k] @ beta)


def combine(screen: Screen, parts: list[Candidate]) -> Candidate:
    """One candidate of a mechanism acting at several places at once (amplitudes fitted jointly)."""
    first = parts[0]
    nonneg = _nonneg_first(screen, first)
    gram = _gram(screen, parts)
    tot = gram.sum(axis=0)
    betas = [_solve(tot[g], nonneg and g == 0) for g in range(len(screen.groups))]
    gains = np.array([_gain(tot[g], betas[g]) for g in range(len(screen.groups))])
    nb = gram.shape[0]
    cv_blocks = np.zeros((nb, len(screen.groups)))
    for blk in range(nb):
        rest = tot - gram[blk]
        cv_blocks[blk] = [_gain(gram[blk, g], _solve(rest[g], nonneg and g == 0)) for g in range(len(screen.groups))]
    dof = sum(p.dof for p in parts)
    dsse = float(gains.sum())
    out = Candidate(first.mechanism, first.options, first.shape, first.network, first.free,
                    sum(p.response for p in parts), first.signature,
                    f"{first.mechanism} at {' + '.join(_place_text(p.options) for p in parts)}", first.factory)
    out.parts = parts
    out.part_betas = [float(betas[0][i]) if screen.temps_first else 0.0 for i in range(len(parts))]
    out.dsse, out.dsse_bal, out.dof = dsse, float(screen.weights @ gains), dof
    out.lr, out.p_value = max(dsse, 0.0), float(stats.chi2.sf(max(dsse, 0.0), dof))
    out.cv_blocks, out.group_gain = cv_blocks, gains
    out.cv_gain, out.cv_wins = cv_of(screen.weights, cv_blocks)
    out.beta = first.beta
    out.block_stats, out.projected = first.block_stats, first.projected
    out.gram = gram
    return out


def restricted(screen: Screen, cand: Candidate, keep: np.ndarray) -> Candidate:
    """``cand`` with its amplitudes fitted on the blocks marked ``keep`` alone (bool per block)."""
    nonneg = _nonneg_first(screen, cand)
    if not cand.parts:
        beta = _beta(cand.block_stats[keep].sum(axis=0), nonneg)
        return replace(cand, beta={n: float(b) for n, b in zip(screen.group_names, beta)})
    tot = cand.gram[keep].sum(axis=0)
    first = _solve(tot[0], nonneg) if screen.temps_first else np.zeros(len(cand.parts))
    return replace(cand, part_betas=[float(b) for b in first])


def _place_text(options: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v if isinstance(v, str) else '+'.join(map(str, v))}" for k, v in options.items()) \
        or "default place"


def best_compound(screen: Screen, singles: list[Candidate], max_places: int = 3, gain: float = 1.1) -> Candidate:
    """Greedily add the mechanism's next-best places while the joint balanced gain grows by ``gain``×."""
    ranked = sorted(singles, key=lambda c: -c.dsse_bal)
    current = ranked[0]
    chosen = [ranked[0]]
    for nxt in ranked[1:]:
        if len(chosen) >= max_places:
            break
        if nxt.shape != chosen[0].shape or nxt.options == chosen[0].options:
            continue
        trial = combine(screen, chosen + [nxt])
        if trial.dsse_bal > gain * current.dsse_bal and all(b >= 0 for b in getattr(trial, "part_betas", [])):
            chosen.append(nxt)
            current = trial
    return current
