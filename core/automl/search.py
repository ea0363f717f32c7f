"""The search: a portfolio first, then successive halving of the networks on epochs (a network far behind the
best pipeline is dropped at its lowest fidelity), then Optuna's TPE over the conditional space of the promising
cheap families with the budget left, then the final choice.

A TPE candidate's settings were chosen on the very folds that score it, so its score is optimistic (and more so
the more trials TPE compares): it enters the final choice only when it beats the best a-priori candidate by more
than one standard error of their per-fold differences (:func:`earns_its_place`; with one fold, never). The final
choice is the average of the candidates the folds cannot tell from the best by that same rule, each weighted by
the inverse of its mean squared fold RMSE (:meth:`Search._hedge`, :func:`inverse_mse_weights`) when there are two
or more, else the greedy ensemble when it wins, else the best pipeline. On a sparse target (a drift measured now
and then) a candidate with more fitted parameters than readings never gets a score (:mod:`.evaluate`).

The budget counts fits (one candidate costs one fit per inner fold), so a run is deterministic for a seed;
``timeout_s`` adds a wall-clock limit, which makes the result depend on the machine's load. Every candidate is
one trial of an Optuna study (portfolio and promoted candidates are enqueued trials carrying the candidate as a
user attribute; TPE trials sample the space), so a re-run with the same storage resumes: finished trials count
against the budget and are not run again.
"""

from __future__ import annotations

import json
import os
import sys
import time
import warnings
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import optuna

from thermodrift.core import resume
from thermodrift.core.automl import space
from thermodrift.core.automl.ensemble import caruana, out_of_fold
from thermodrift.core.automl.evaluate import Evaluation, Evaluator, Underdetermined
from thermodrift.core.automl.folds import aggregate

PHASE_ATTR = "automl.phase"
PROMOTE_WITHIN = 1.5  # a network is trained longer only while its score is within this factor of the best


@dataclass
class Settings:
    """``budget_fits``: fits in all (default sized for ≤ 10 min on FL_THERMAL, 2 cores); ``timeout_s``: optional
    wall-clock limit (load-dependent); ``max_folds``: inner folds; ``tpe_families``: how many of the best
    cheap families (by their portfolio score) TPE searches; ``top_rung``: network fidelities above the portfolio's;
    ``ensemble_pool``: candidates the greedy ensemble draws from; ``families``: restrict to these models;
    ``n_jobs``: worker processes for the inner folds and the portfolio (None: the cores; the result does not
    depend on it)."""

    budget_fits: int = 120
    timeout_s: float | None = None
    max_folds: int = 3
    tpe_families: int = 4
    top_rung: int = 3
    ensemble_pool: int = 10
    ensemble_steps: int = 25
    families: list[str] | None = None
    n_jobs: int | None = None

    def jobs(self) -> int:
        """Worker processes for the inner folds and the portfolio: ``n_jobs``, or the cores this process may use."""
        if self.n_jobs is not None:
            if int(self.n_jobs) < 1:
                from thermodrift.core.errors import InputError
                raise InputError(f"automl.n_jobs must be 1 or more (or null: the cores), got {self.n_jobs}")
            return int(self.n_jobs)
        return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


@dataclass
class Entry:
    """One leaderboard line: a candidate, its evaluation (None when it failed) and the error."""

    number: int
    candidate: space.Candidate
    evaluation: Evaluation | None
    error: str = ""
    phase: str = ""

    @property
    def score(self) -> float:
        return self.evaluation.score if self.evaluation is not None else float("inf")


@dataclass
class SearchResult:
    entries: list[Entry]
    best: Entry
    ensemble: dict | None  # {"members": [...params], "weights": [...], "score", "fold_rmse"} when it won
    fits: int
    folds: list = field(default_factory=list)
    stopped_by: str = "budget"

    def chosen(self) -> tuple[str, dict]:
        """The registry model and parameters of the result: an ensemble when it beat the best pipeline."""
        if self.ensemble is not None:
            return "ensemble", {"members": self.ensemble["members"], "weights": self.ensemble["weights"]}
        return "pipeline", dict(self.best.candidate.params)


class Search:
    """Runs the search of ``settings`` with ``evaluator`` in ``study`` (an Optuna study, usually in storage)."""

    def __init__(self, evaluator: Evaluator, study: optuna.Study, settings: Settings,
                 say: Callable[[str], None] = lambda line: None, progress: bool = True):
        self.ev, self.study, self.settings, self.say, self.progress = evaluator, study, settings, say, progress
        self.families = {f.name: f for f in space.families(only=settings.families, roles=evaluator.roles)}
        self.selectors = space.selectors()
        self.n_folds = len(evaluator.folds)
        self.memory: dict[int, Evaluation] = {}  # this process's evaluations (with predictions) by trial number
        self.failed_families: set[str] = set()
        self.underdetermined: set[str] = set()  # families named once as having a candidate left out for it
        self.started = time.perf_counter()
        self.stopped_by = "budget"
        self.bar = None

    # ------------------------------------------------------------------------------------------------ budget
    def fits_used(self) -> int:
        return sum(int(t.user_attrs.get("fits", 0)) for t in self.study.trials if t.state.is_finished())

    def _room(self) -> bool:
        if self.settings.timeout_s is not None and time.perf_counter() - self.started > self.settings.timeout_s:
            self.stopped_by = "timeout_s (wall clock)"
            return False
        return self.fits_used() + self.n_folds <= self.settings.budget_fits

    # ------------------------------------------------------------------------------------------------ phases
    def run(self) -> SearchResult:
        resume.fail_dead_trials(self.study)
        if self.progress:
            from tqdm import tqdm
            self.bar = tqdm(total=self.settings.budget_fits, initial=min(self.fits_used(), self.settings.budget_fits),
                            unit="fit", desc="automl", file=sys.stderr, dynamic_ncols=True)
        try:  # the worker processes (n_jobs) serve the phases and the final choice's recomputed predictions
            try:
                self._phase("portfolio", lambda: [(c, "portfolio") for c in
                                                  space.portfolio(list(self.families.values()), self.selectors)])
                self._promote()
                self._tpe()
            finally:
                if self.bar is not None:
                    self.bar.close()
            entries = self.entries()
            ok = [e for e in entries if e.evaluation is not None]
            if not ok:
                from thermodrift.core.errors import InputError
                reasons = sorted({e.error for e in entries})
                raise InputError(f"every automl candidate failed: {'; '.join(reasons)[:300]}")
            eligible = self._eligible(ok)
            best = self._best(eligible)
            ensemble = self._hedge(eligible, best) or self._ensemble(eligible, best)
        finally:
            self.ev.close()
        return SearchResult(entries, best, ensemble, self.fits_used(), self.ev.folds, self.stopped_by)

    def _phase(self, name: str, make: Callable[[], list[tuple[space.Candidate, str]]]) -> None:
        """Enqueue the phase's candidates once (a resumed study keeps them) and run the waiting trials."""
        key = f"{PHASE_ATTR}.{name}"
        if key not in self.study.user_attrs:
            for cand, phase in make():
                self.study.enqueue_trial({}, user_attrs={"candidate": cand.to_json(), "phase": phase},
                                         skip_if_exists=False)
            self.study.set_user_attr(key, True)
        while self._waiting() and self._room():
            if self.ev.n_jobs == 1:
                self._trial()
            else:  # the trials the budget has room for, evaluated at once, told in trial order
                room = (self.settings.budget_fits - self.fits_used()) // max(1, self.n_folds)
                waiting = sum(t.state == optuna.trial.TrialState.WAITING for t in self.study.trials)
                self._batch(max(1, min(room, waiting)))

    def _waiting(self) -> bool:
        return any(t.state == optuna.trial.TrialState.WAITING for t in self.study.trials)

    def _tpe(self) -> None:
        """TPE over the settings of the best cheap families: a medium or expensive family's fit costs minutes, so
        it takes part untuned (and, for a network, through successive halving), which keeps the default budget
        within its time. A sparse target (:mod:`.evaluate`) is not tuned: its inner folds hold a handful of
        measured rows, on which tuned settings fit the noise of those very rows, so the a-priori candidates decide."""
        if self.ev.max_parameters is not None:
            self.say(f"automl: no TPE tuning: the target is measured on {self.ev.max_parameters} training rows only "
                     "(a-priori candidates only)")
            return
        ranked = [f for f in self._family_ranking() if self.families[f].cost == "cheap"]
        chosen = [f for f in ranked if f not in self.failed_families][:self.settings.tpe_families]
        if not chosen:
            return
        fams = [self.families[f] for f in sorted(chosen)]
        while self._room():
            self._trial(lambda trial: space.suggest(trial, fams, self.selectors))

    def _promote(self) -> None:
        """Successive halving on epochs: the best third of each network family's candidates at a rung is retrained
        at the next rung (3× the epochs), up to ``top_rung``."""
        for rung in range(1, self.settings.top_rung + 1):
            key = f"{PHASE_ATTR}.rung{rung}"

            def make(rung=rung) -> list[tuple[space.Candidate, str]]:
                out = []
                entries = [e for e in self.entries() if e.evaluation is not None]
                overall = min((e.score for e in entries), default=float("inf"))
                for fam in (f for f in self.families.values() if f.network):
                    at = sorted((e for e in entries if e.candidate.family == fam.name
                                 and e.candidate.rung == rung - 1), key=lambda e: e.score)
                    keep = at[:max(1, len(at) // space.RUNG_EPOCH_FACTOR)] if at else []
                    # a network far behind the best pipeline is not worth more epochs
                    for e in keep:
                        if e.score <= PROMOTE_WITHIN * overall:
                            out.append((space.Candidate(e.candidate.params, rung, "promoted",
                                                        f"rung {rung} of #{e.number}"), f"rung{rung}"))
                return out
            if key not in self.study.user_attrs and not self._room():
                return
            self._phase(f"rung{rung}", make)

    # ------------------------------------------------------------------------------------------------ trials
    def _trial(self, sample: Callable[[optuna.Trial], space.Candidate] | None = None) -> None:
        trial, cand, params = self._ask(sample)
        if params is not None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out = self.ev.evaluate_many([params])[0]
            self._tell(trial, cand, out)

    def _batch(self, count: int) -> None:
        """``count`` waiting (enqueued) trials: asked in order, their folds fitted in parallel, told in order. A
        family that fails in an earlier trial of the batch skips its later ones, as one trial at a time would."""
        asked = [self._ask() for _ in range(count)]
        todo = [(trial, cand, params) for trial, cand, params in asked if params is not None]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            outs = self.ev.evaluate_many([params for _, _, params in todo])
        for (trial, cand, _), out in zip(todo, outs):
            if cand.family in self.failed_families:
                self._skip(trial, "its family failed before")
            else:
                self._tell(trial, cand, out)

    def _ask(self, sample: Callable[[optuna.Trial], space.Candidate] | None = None):
        """The next trial, its candidate and its parameters (None when the trial was skipped)."""
        with warnings.catch_warnings():  # ask/tell: the trials' owner attribute marks a killed run's trials
            warnings.simplefilter("ignore", UserWarning)
            trial = self.study.ask()
        resume.claim(trial)
        text = trial.user_attrs.get("candidate")
        cand = space.Candidate.from_json(text) if text else sample(trial)
        if not text:
            trial.set_user_attr("candidate", cand.to_json())
            trial.set_user_attr("phase", "tpe")
        family = self.families.get(cand.family)
        if family is None or cand.family in self.failed_families:
            self._skip(trial, "its family failed before" if family else "unknown family")
            return trial, cand, None
        trial.set_user_attr("fits", self.n_folds)
        return trial, cand, space.at_rung(cand, cand.rung, family, self.settings.top_rung)

    def _skip(self, trial: optuna.Trial, why: str) -> None:
        trial.set_user_attr("fits", 0)
        trial.set_user_attr("skipped", why)
        self.study.tell(trial, state=optuna.trial.TrialState.FAIL)

    def _tell(self, trial: optuna.Trial, cand: space.Candidate, ev: Evaluation | Exception) -> None:
        """Record a candidate's evaluation, or its failure (the search goes on; a portfolio failure leaves its
        family out). A candidate underdetermined by a sparse target's measurements (:class:`Underdetermined`) is
        left out alone, unscored and so not counted in the budget, and its family is named once with why."""
        if isinstance(ev, Underdetermined):
            trial.set_user_attr("fits", 0)
            trial.set_user_attr("error", f"left out: {ev}")
            self.study.tell(trial, state=optuna.trial.TrialState.FAIL)
            if cand.family not in self.underdetermined:
                self.underdetermined.add(cand.family)
                self.say(f"automl: {space.describe(cand.params)} left out: {ev}, where the target is measured"
                         f" now and then (later {cand.family} candidates with as many are left out too)")
            self._tick()
            return
        if isinstance(ev, Exception):
            reason = f"{type(ev).__name__}: {' '.join(str(ev).split())}"[:400]
            trial.set_user_attr("error", reason)
            self.study.tell(trial, state=optuna.trial.TrialState.FAIL)
            if trial.user_attrs.get("phase") == "portfolio" and cand.family not in self.failed_families:
                self.failed_families.add(cand.family)
                self.say(f"thermodrift: warning: automl: model {cand.family} failed and is left out: {reason}")
            self._tick()
            return
        params = space.at_rung(cand, cand.rung, self.families[cand.family], self.settings.top_rung)
        for key, value in {"fold_rmse": ev.fold_rmse, "target_rmse": ev.target_rmse, "fit_s": ev.fit_s,
                           "costs": ev.costs, "params": params}.items():
            trial.set_user_attr(key, json.loads(json.dumps(value, default=float)))
        self.study.tell(trial, ev.score)
        self.memory[trial.number] = ev
        self._tick()

    def _tick(self) -> None:
        if self.bar is None:
            return
        self.bar.n = min(self.fits_used(), self.settings.budget_fits)
        scores = [t.value for t in self.study.trials if t.state == optuna.trial.TrialState.COMPLETE]
        if scores:
            self.bar.set_postfix_str(f"best inner score {min(scores):.3f} {self.ev.unit}", refresh=False)
        self.bar.refresh()

    # ------------------------------------------------------------------------------------------------ results
    def entries(self) -> list[Entry]:
        """Every finished candidate trial, failed ones included, in trial order."""
        out = []
        for t in self.study.trials:
            if not t.state.is_finished() or "candidate" not in t.user_attrs or "skipped" in t.user_attrs:
                continue
            cand = space.Candidate.from_json(t.user_attrs["candidate"])
            ev = None
            if t.state == optuna.trial.TrialState.COMPLETE:
                ev = self.memory.get(t.number) or Evaluation(
                    list(t.user_attrs["fold_rmse"]), dict(t.user_attrs["target_rmse"]), float(t.value), [],
                    float(t.user_attrs.get("fit_s", 0.0)), dict(t.user_attrs.get("costs", {})))
            out.append(Entry(t.number, cand, ev, t.user_attrs.get("error", ""), t.user_attrs.get("phase", "")))
        return out

    def _family_ranking(self) -> list[str]:
        best: dict[str, float] = {}
        for e in self.entries():
            if e.evaluation is not None:
                best[e.candidate.family] = min(best.get(e.candidate.family, np.inf), e.score)
        return sorted(best, key=lambda f: (best[f], f))

    def _full(self, e: Entry) -> bool:
        """Whether ``e`` was trained as its refit will be: any family but a network below its top rung."""
        fam = self.families.get(e.candidate.family)
        return fam is None or not fam.network or e.candidate.rung == self.settings.top_rung

    def _best(self, ok: list[Entry]) -> Entry:
        """The best candidate by score among those trained as the refit will be (else among all)."""
        return min([e for e in ok if self._full(e)] or ok, key=lambda e: (e.score, e.number))

    def _eligible(self, ok: list[Entry]) -> list[Entry]:
        """The candidates the final choice (best pipeline and ensemble pool) draws from: every a-priori one
        (portfolio, promoted) and the TPE ones that earn their place against the best a-priori candidate."""
        prior = [e for e in ok if e.phase != "tpe" and self._full(e)]
        if not prior:
            return ok
        keep, ref = eligible(ok, prior)
        if len(keep) < len(ok):
            self.say(f"automl: {len(ok) - len(keep)} TPE candidate(s) left out of the final choice: tuned on the "
                     f"folds that score them, they do not beat trial {ref.number} ({space.describe(ref.candidate.params)}"
                     f") by more than one standard error across the folds")
        return keep

    def _predictions(self, e: Entry) -> list[np.ndarray]:
        """``e``'s inner-fold predictions; a resumed run recomputes those it does not hold (deterministic, not
        budgeted)."""
        if e.evaluation is None or not e.evaluation.predictions:
            fam = self.families[e.candidate.family]
            e.evaluation = self.ev.evaluate(space.at_rung(e.candidate, e.candidate.rung, fam, self.settings.top_rung),
                                            measure_costs=False)
        return e.evaluation.predictions

    def _hedge(self, ok: list[Entry], best: Entry) -> dict | None:
        """The average of every candidate the inner folds cannot tell from the best: those the best does not beat
        by more than one standard error of their per-fold differences (the one-standard-error rule's set;
        :func:`earns_its_place` with the roles turned), each weighted by the inverse of its mean squared fold RMSE
        (:func:`inverse_mse_weights`). Inside that set the folds rank by noise, and on a new working condition the
        candidates extrapolate differently (filter banks, penalties, physics), so weights fitted on the same folds
        would fit their noise; fixed weights hedge across them (model averaging under model uncertainty), and the
        inverse-MSE ones give less to a member whose fold errors swing (a wide standard error keeps it in the set).
        Each a-priori candidate (fixed in advance as a distinct hypothesis) takes part, but of TPE's candidates
        only each family's best: they are variations around one mode of the sampler (at a larger budget dozens of
        near-copies) and would otherwise outvote the rest. Identical predictions (one model under two names, a
        setting without effect) count once; at most ``ensemble_pool`` members, best first. None with one inner fold
        (no noise to estimate) or when fewer than two members remain: then the greedy ensemble decides
        (:meth:`_ensemble`)."""
        if len(self.ev.folds) < 2:
            return None
        ordered = sorted((e for e in ok if self._full(e)), key=lambda e: (e.score, e.number))
        members = one_se_set(ordered, best.evaluation.fold_rmse, self._predictions, self.settings.ensemble_pool)
        if len(members) < 2:
            return None
        entries = [e for e, _ in members]
        chosen = self._mixture(entries, [p for _, p in members], inverse_mse_weights(entries),
                               "one-SE set, inverse-MSE weights")
        self.say(f"automl: the inner folds cannot tell {len(members)} candidates from the best (one standard error "
                 f"of their per-fold differences); their average weighted by inverse mean squared fold RMSE is "
                 f"chosen (inner score {chosen['score']:.3f} {self.ev.unit}, best single {best.score:.3f} {self.ev.unit})")
        return chosen

    def _mixture(self, entries: list[Entry], preds: list[list[np.ndarray]], weights: list[float], kind: str) -> dict:
        """The final choice's description: ``entries`` at the refit's fidelity with ``weights``, scored on the
        inner folds by their weighted predictions ``preds``."""
        mix = [sum(w * p[k] for w, p in zip(weights, preds)) for k in range(len(self.ev.folds))]
        fold_rmse, agg = self.ev.score_predictions(mix)
        top = self.settings.top_rung
        return {"members": [space.at_rung(e.candidate, e.candidate.rung, self.families[e.candidate.family], top)
                            for e in entries],
                "weights": [float(w) for w in weights], "numbers": [e.number for e in entries], "score": agg,
                "fold_rmse": fold_rmse, "kind": kind}

    def _ensemble(self, ok: list[Entry], best: Entry) -> dict | None:
        """Greedy ensemble over a diverse pool: the best candidate of each family on each input set (raw, each
        filter bank; members that err differently are what an ensemble gains from), best first. Kept when it beats
        the best pipeline on the inner folds and, with two folds or more, also out of fold
        (:func:`thermodrift.core.automl.ensemble.out_of_fold`)."""
        pool = diverse_pool(sorted((e for e in ok if self._full(e)), key=lambda e: (e.score, e.number)),
                            self.settings.ensemble_pool)
        if len(pool) < 2:
            return None
        preds = [self._predictions(e) for e in pool]
        weights, score, oof = greedy_weights(preds, lambda p: self.ev.score_predictions(p)[1], self.ev.fold_rmse,
                                             best.score, self.settings.ensemble_steps)
        if weights is None:
            if oof is not None:
                self.say(f"automl: the greedy ensemble (inner score {score:.3f} {self.ev.unit}) is not kept: out of fold "
                         f"it scores {oof[0]:.3f} against {oof[1]:.3f} {self.ev.unit} for choosing one pipeline")
            return None
        used = np.flatnonzero(weights > 0)
        return self._mixture([pool[i] for i in used], [preds[i] for i in used], [weights[i] for i in used], "greedy")


def eligible(ok: Sequence[Entry], prior: Sequence[Entry]) -> tuple[list[Entry], Entry]:
    """Of ``ok``, every a-priori candidate and the TPE ones that beat the best of ``prior`` (the a-priori candidates
    trained as their refit will be) by one standard error across the folds (:func:`earns_its_place`); and that
    best."""
    ref = min(prior, key=lambda e: (e.score, e.number))
    return [e for e in ok if e.phase != "tpe" or earns_its_place(e.evaluation.fold_rmse,
                                                                 ref.evaluation.fold_rmse)], ref


def one_se_set(ordered: Sequence[Entry], best_fold_rmse: list[float],
               predictions: Callable[[Entry], list[np.ndarray]], pool: int,
               key: Callable[[Entry], object] | None = None) -> list[tuple[Entry, list[np.ndarray]]]:
    """The members of :meth:`Search._hedge`'s average and their inner-fold predictions: of ``ordered`` (best
    first), every candidate with a finite score that the best (per-fold RMSEs ``best_fold_rmse``, µm) does not beat
    by one standard error, of TPE's only each family's first, predictions identical to a member's once, at most
    ``pool``. ``key``: also at most one member per key (a variant the benchmark replays)."""
    members: list[tuple[Entry, list[np.ndarray]]] = []
    tuned: set[str] = set()
    keys: set = set()
    for e in ordered:
        if not np.isfinite(e.score) or earns_its_place(best_fold_rmse, e.evaluation.fold_rmse) or (
                e.phase == "tpe" and e.candidate.family in tuned):
            continue
        if e.phase == "tpe":
            tuned.add(e.candidate.family)
        k = key(e) if key is not None else None
        if k is not None and k in keys:
            continue
        preds = predictions(e)
        if any(all(np.allclose(p, q) for p, q in zip(preds, other)) for _, other in members):
            continue
        keys.add(k)
        members.append((e, preds))
        if len(members) == pool:
            break
    return members


def inverse_mse_weights(members: Sequence[Entry]) -> list[float]:
    """Weights of :meth:`Search._hedge`'s average: each member's inverse mean squared fold RMSE (µm⁻²), normalised
    to sum to one (Bates and Granger's combination of forecasts, 1969, without the covariances that two or three
    folds cannot estimate); members without fold error share all the weight."""
    mse = np.array([np.mean(np.square(e.evaluation.fold_rmse)) for e in members], dtype=float)
    inverse = (mse == 0).astype(float) if (mse == 0).any() else 1.0 / mse
    return [float(w) for w in inverse / inverse.sum()]


def family_and_inputs(e: Entry) -> tuple[str, str]:
    """A candidate's family and input set (raw or a filter bank's settings)."""
    return e.candidate.family, json.dumps(e.candidate.params.get("features"), sort_keys=True)


def diverse_pool(ordered: Sequence[Entry], pool: int) -> list[Entry]:
    """The greedy ensemble's pool: the first (best) candidate of ``ordered`` per family and input set, at most
    ``pool``; members that err differently are what an ensemble gains from."""
    out, seen = [], set()
    for e in ordered:
        key = family_and_inputs(e)
        if key not in seen:
            seen.add(key)
            out.append(e)
        if len(out) == pool:
            break
    return out


def greedy_weights(preds: list[list[np.ndarray]], score: Callable[[list[np.ndarray]], float],
                   fold_rmse: Callable[[np.ndarray, int], float], best_score: float, steps: int
                   ) -> tuple[np.ndarray | None, float, tuple[float, float] | None]:
    """Caruana weights over the candidates' inner-fold predictions ``preds``, kept when two members or more beat
    ``best_score`` (µm) on the inner folds and, with two folds or more, also out of fold
    (:func:`thermodrift.core.automl.ensemble.out_of_fold`): (weights or None, their inner score, (ensemble,
    single pipeline) out of fold when that test ran)."""
    weights, inner = caruana(preds, score, steps)
    if np.count_nonzero(weights > 0) < 2 or not inner < best_score:
        return None, inner, None
    ens_oof, single_oof = out_of_fold(preds, fold_rmse, aggregate, steps)
    if np.isfinite(ens_oof) and not ens_oof < single_oof:
        return None, inner, (ens_oof, single_oof)
    return weights, inner, (ens_oof, single_oof)


def earns_its_place(tuned: list[float], reference: list[float]) -> bool:
    """Whether a candidate tuned on the inner folds (``tuned``: its per-fold RMSEs, µm) beats one chosen before
    looking at them (``reference``) by more than one standard error of the per-fold differences (the one-SE rule of
    Breiman et al., 1984, applied to the gain of tuning). With two folds this means better on both; with one fold
    the noise cannot be estimated, so no gain is shown."""
    d = np.asarray(tuned, dtype=float) - np.asarray(reference, dtype=float)
    if len(d) < 2 or not np.isfinite(d).all():
        return False
    return bool(d.mean() + d.std(ddof=1) / np.sqrt(len(d)) < 0)
