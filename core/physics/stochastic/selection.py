"""Forward selection of a building's structure (Bacher & Madsen 2011): from the one-state model, each round fits
every one-step extension of the current model (each building mechanism that has a place in it), keeps the best
by likelihood and accepts it when the likelihood-ratio test against the current model is significant at
``alpha`` (default 0.05, the field's usual level): LR = 2 (ℓ₁ − ℓ₀) ~ χ²(k₁ − k₀). Otherwise it stops.

Starts: the one-state model from a least-squares fit of its Euler discretisation (ΔTi/Δt on Ta − Ti, Ps and the
heating), so the search begins at the recording's own heat and irradiance scales; each extension from the current
model's estimates plus the mechanism's defaults rescaled to that heat scale (:func:`~.building.rescaled`; a new
aperture at the interior aperture's estimate), again with the new state fast (nearly the parent) and with the
parameters the parent left on a bound moved back to where they started (:func:`extension_starts`), and
``starts − 1`` more points drawn from ``seed``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from thermodrift.core.physics.stochastic import whiteness
from thermodrift.core.physics.stochastic.building import htc, rescaled, structure_name
from thermodrift.core.physics.stochastic.fit import Estimate, fit
from thermodrift.core.physics.stochastic.rc import RCNetwork
from thermodrift.core.physics.stochastic.sde import Series

ALPHA = 0.05
DEFAULT_HTC = 0.2  # the building mechanisms' defaults: 1 / Ria = 1 / (5 K/kW)
FAST = 1e-3        # a new state's capacity in the "fast" start, relative to its default


@dataclass
class Step:
    """One accepted model (or the last rejected best): its name, estimate, LR test against its parent."""

    name: str
    estimate: Estimate
    lr: float | None = None
    df: int | None = None
    p_value: float | None = None
    accepted: bool = True
    whiteness: dict = field(default_factory=dict)
    candidates: list[dict] = field(default_factory=list)

    def record(self) -> dict:
        """JSON-ready: name, loglik, n_params, lr, df, p_value, accepted, whiteness, candidates, seconds."""
        return {"name": self.name, "loglik": self.estimate.loglik, "n_params": self.estimate.n_params,
                "lr": self.lr, "df": self.df, "p_value": self.p_value, "accepted": self.accepted,
                "whiteness": self.whiteness, "candidates": self.candidates,
                "seconds": round(self.estimate.seconds, 2)}


@dataclass
class Selection:
    """The path (first: the one-state model; last may be a rejected extension) and the selected estimate."""

    path: list[Step]
    selected: Step
    alpha: float
    seconds: float
    n_evals: int = 0  # filter passes of every fit (each gradient evaluation counts one), the intervals' included


def ti_start(net: RCNetwork, data: Series) -> RCNetwork:
    """Start values of the one-state model from a least-squares fit of its Euler discretisation (see the module
    docstring); the defaults where the fit gives a non-physical sign."""
    names = net.input_names
    ta, phi = names.index(net.input_of("ambient")), names.index(net.input_of("heating"))
    solar = names.index(net.input_of("solar_irradiance")) if net.has_input("solar_irradiance") else None
    y, u, dt = data.y[:, 0], data.u, np.diff(data.t)
    cols = [(u[:-1, ta] - y[:-1]), u[:-1, phi]] + ([u[:-1, solar]] if solar is not None else [])
    X = np.column_stack(cols)
    rate = np.diff(y) / dt
    coef, *_ = np.linalg.lstsq(X, rate, rcond=None)
    a, c = coef[0], coef[1]
    if not (a > 0 and c > 0):
        return net
    ci = 1.0 / c
    values = {"Ci": ci, "Ria": 1.0 / (a * ci), "sigma_ti": float(np.std(rate - X @ coef) * math.sqrt(np.median(dt)))}
    if solar is not None:  # the regression's aperture, else one whose mean gain is 1 % of the mean heating
        ps, q = float(np.mean(u[:, solar])), float(np.mean(u[:, phi]))
        values["Aw"] = coef[2] * ci if coef[2] > 0 else (0.01 * q / ps if ps > 0 and q > 0 else 0.0)
    return net.with_values({k: v for k, v in values.items() if v > 0})


def _whiteness(est: Estimate) -> dict:
    return whiteness.summary(est.filtered().standardized[:, 0])


def _fit_one(job: tuple) -> Estimate:
    model, data, seed, starts, also = job
    return fit(model, data, seed=seed, starts=starts, information=False, also=also)


def _fit_all(jobs: list[tuple[RCNetwork, list[dict]]], data: Series, seed: int, starts: int,
             workers: int) -> list[Estimate]:
    """Fit each (model, more start points) (in ``workers`` processes when more than one: the candidates of a
    round are independent, and each fit is deterministic, so the result does not depend on ``workers``)."""
    jobs = [(m, data, seed, starts, also) for m, also in jobs]
    if workers <= 1 or len(jobs) <= 1:
        return [_fit_one(j) for j in jobs]
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(min(workers, len(jobs))) as pool:
        return list(pool.map(_fit_one, jobs))


def extension_starts(parent: Estimate, ext: RCNetwork, scale: float, origin: dict[str, float]
                     ) -> tuple[RCNetwork, list[dict]]:
    """An extension of ``parent``'s model with its start points: the parent's estimates with the new parameters at
    their defaults rescaled to the recording's heat scale (a new aperture at the interior's), and, when a parent
    parameter ended on a bound, the same with those parameters back at the values they started from when they
    entered the model (``origin``): a state the parent lacked often needs what the parent switched off, e.g. the
    interior's solar aperture, and a search cannot leave a bound that the likelihood is flat at. One more start
    has the new capacities ``FAST`` times smaller: a new state that fast follows its neighbours, so the extension
    starts close to its parent's likelihood and a fit that finds nothing more ends near it, not below it."""
    params = parent.model.parameters
    base = dict(parent.values)
    defaults = rescaled(ext, scale if math.isfinite(scale) and scale > 0 else 1.0).values()
    new = set(defaults) - set(base)
    start = {**base, **{k: defaults[k] for k in new}}
    bounded = {p.name for p, e in zip(params, parent.eta) if p.at_bound(e) and p.name in origin}
    if "Aw" in base and "Aw" not in bounded:  # apertures start at the interior's: irradiance units vary
        start.update({k: base["Aw"] for k in new if k.startswith("A")})
    reset = {**start, **{k: origin[k] for k in bounded}}
    if "Aw" in bounded:
        reset.update({k: origin["Aw"] for k in new if k.startswith("A")})
    fast = {**start, **{k: start[k] * FAST for k in new if k.startswith("C")}}
    return ext.with_values(start), [fast] + ([reset] if bounded else [])


def forward_select(net: RCNetwork, data: Series, *, registry=None, seed: int = 0, starts: int = 2,
                   alpha: float = ALPHA, progress=None, workers: int = 1, only=None) -> Selection:
    """Forward selection from ``net`` (the one-state model; see the module docstring). ``progress``: called
    with a line of text per fitted candidate; ``workers``: processes fitting a round's candidates; ``only``:
    mechanism ids to consider (default: every registered building mechanism)."""
    from thermodrift.core.physics.stochastic.building import BuildingMechanism

    if registry is None:
        from thermodrift.core import registry as registry_module

        registry = registry_module.default()
    mechs = [registry.get("mechanism", m).factory for m in registry.names("mechanism") if only is None or m in only]
    mechs = [m for m in mechs if isinstance(m, type) and issubclass(m, BuildingMechanism)]
    clock = time.perf_counter()
    first = ti_start(net, data)
    origin = first.values()  # each parameter's start value when it entered the model
    est = fit(first, data, seed=seed, starts=starts, information=False)
    current = Step(structure_name(net), est, whiteness=_whiteness(est))
    if progress:
        progress(f"{current.name}: loglik {est.loglik:.1f}")
    path = [current]
    n_evals = est.n_evals
    while True:
        scale = htc(current.estimate.model, current.estimate.values) / DEFAULT_HTC
        base = current.estimate.model.with_values(current.estimate.values)
        jobs = [extension_starts(current.estimate, m().apply(base), scale, origin) for m in mechs if m.places(base)]
        tried = _fit_all(jobs, data, seed, starts, workers)
        n_evals += sum(e.n_evals for e in tried)
        if progress:
            for e in tried:
                progress(f"  {structure_name(e.model)}: loglik {e.loglik:.1f} ({e.n_evals} filter passes, "
                         f"{e.seconds:.1f} s)")
        if not tried:
            break
        best = max(tried, key=lambda e: e.loglik)
        df = best.n_params - current.estimate.n_params
        lr = max(2.0 * (best.loglik - current.estimate.loglik), 0.0)
        p = float(chi2.sf(lr, df))
        step = Step(structure_name(best.model), best, lr, df, p, p < alpha, _whiteness(best),
                    [{"name": structure_name(e.model), "loglik": e.loglik, "n_params": e.n_params} for e in tried])
        path.append(step)
        if not step.accepted:
            break
        origin.update({k: v for k, v in best.model.values().items() if k not in origin})
        current = step
    from thermodrift.core.physics.stochastic.fit import add_information

    before = current.estimate.n_evals
    add_information(current.estimate)
    n_evals += current.estimate.n_evals - before
    return Selection(path, current, alpha, time.perf_counter() - clock, n_evals)
