"""Population metaheuristics as Optuna samplers whose whole state lives in Optuna storage.

Contract for subclasses (PSO, GWO, FA, RBMO, RBMO-X): set ``prefix`` (the attribute namespace) and
``generational``, implement :meth:`PopulationSampler._propose`, and for generational algorithms optionally
:meth:`PopulationSampler._replaces`. Everything else is here.

Call order (Optuna's): ``before_trial`` -> ``infer_relative_search_space`` -> ``sample_relative`` (lazily, at the
first ``suggest_*`` of a relative parameter) -> ``sample_independent`` for every parameter outside the relative
space -> ``after_trial``. All work happens in ``sample_relative``, under a lock so threads (``n_jobs > 1``) never
take the same slot:

1. Encode the relative search space (the intersection of the finished trials' spaces, single-valued parameters
   left out, parameters sorted by name) into the unit cube [0, 1]^D with Optuna's transform: one column per float
   or int (log scale where ``log=True``; int and stepped float widened by half a step so rounding is fair),
   categorical one-hot, decoded by argmax. Step sizes, velocity limits and attraction ranges are therefore
   scale-free. Before the first trial finishes the space is empty, so trial 0 is random (as with Optuna's CMA-ES);
   a parameter whose range changes leaves the intersection and is then sampled independently.
2. Read every trial carrying ``<prefix>:space`` equal to this space's signature (trials of another space are
   ignored: a changed space starts a new population). Fitness is the value, negated when maximising; FAIL and
   PRUNED count as +inf (worst); RUNNING and WAITING are pending. Finished trials are parsed once and the
   generational replay (step 3) is kept until a closed generation changes, so an ask costs a few ms at 1000 trials.
3. Give the new trial a slot 0..N-1 and a generation.
   *Asynchronous* algorithms (PSO, GWO): the free slot (its latest trial finished, or none yet) with the fewest
   trials, ties to the lowest index; ``gen`` counts that slot's moves. With more workers than slots, the least
   used busy slot moves again from its latest proposal.
   *Generational* algorithms (FA, RBMO, RBMO-X): generation g closes once N of its trials have finished, as in
   Optuna's ``BaseGASampler``; a new trial takes the first slot of the open generation without a trial, or, when
   all are out, re-proposes the least tried slot still waiting for a result (so a worker killed mid-trial never
   blocks the study). The population after each closed generation is replayed from storage: per slot the best
   finished trial of that generation replaces the stored position when :meth:`_replaces` says so.
4. Draw the trial's random numbers from ``numpy.random.default_rng((seed, trial.number, 0))``. Hence one seed and
   one worker give one trial sequence, threads share no RNG state, a new sampler object on the same storage
   continues exactly where a killed run stopped, and samplers with the same seed start from the same initial
   population (common random numbers for comparisons).
5. Write the per-trial system attributes and decode: ``<prefix>:space`` (signature), ``:slot``, ``:gen``,
   ``:phase`` (e.g. ``init``, ``move``, ``search``, ``attack``), ``:v`` (velocity, for algorithms with one) and
   last ``:x`` (position, D floats in the unit cube), so a reader that sees ``:x`` sees the whole record.

Parameters outside the relative space are drawn as :class:`optuna.samplers.RandomSampler` draws them (uniform in
the transformed space), from a stream seeded by ``(seed, trial.number, crc32(name))``. Schedules that need t/T
read the budget ``n_trials`` given at construction (the study passes its own). Several OS processes may share one
RDB study: each reads the others' trials from storage; two processes asking at the same instant may pick the
same slot, which costs one duplicate proposal.
"""

from __future__ import annotations

import abc
import hashlib
import heapq
import json
import threading
import zlib
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

import numpy as np
import optuna
from optuna._transform import _SearchSpaceTransform  # Optuna's own encoder, shared with its CMA-ES and GP samplers
from optuna.distributions import BaseDistribution, distribution_to_json
from optuna.samplers import BaseSampler
from optuna.search_space import IntersectionSearchSpace
from optuna.study import StudyDirection
from optuna.trial import FrozenTrial, TrialState


@dataclass(frozen=True)
class Member:
    """One trial of the population, read back from storage."""

    number: int
    slot: int
    gen: int
    phase: str
    x: np.ndarray  # position in the unit cube
    v: np.ndarray | None  # velocity, for algorithms that keep one
    fitness: float | None  # None while pending; +inf for FAIL/PRUNED; lower is better

    @property
    def finished(self) -> bool:
        return self.fitness is not None


@dataclass(frozen=True)
class Population:
    """The population after the last closed generation (generational algorithms only)."""

    x: np.ndarray  # (N, D) positions
    fitness: np.ndarray  # (N,), +inf where unknown or failed
    best_x: np.ndarray  # best finished position so far (X_food, the brightest, ...)
    best_fitness: float
    best_history: list[float]  # best fitness after each closed generation


@dataclass(frozen=True)
class Context:
    """What :meth:`PopulationSampler._propose` sees for one new trial."""

    members: list[Member]  # this space's trials, by trial number
    slot: int
    gen: int
    dim: int
    rng: np.random.Generator
    progress: float  # share of the budget n_trials used before this trial (generational: before its generation)
    population: Population | None  # generational algorithms, gen >= 1

    def own(self) -> list[Member]:
        """This slot's earlier trials, oldest first."""
        return [m for m in self.members if m.slot == self.slot]


@dataclass(frozen=True)
class Move:
    """A proposal: position in the unit cube, the phase that produced it, and the velocity if any."""

    x: np.ndarray
    phase: str
    v: np.ndarray | None = None


def best(members: Sequence[Member], k: int = 1) -> list[Member]:
    """The ``k`` best finished members with finite fitness, best first (ties to the earlier trial)."""
    done = (m for m in members if m.fitness is not None and m.fitness < np.inf)
    return heapq.nsmallest(k, done, key=lambda m: (m.fitness, m.number))


class PopulationSampler(BaseSampler, abc.ABC):
    """Base of the population samplers; see the module docstring for the contract.

    Args:
        population_size: N, the number of slots (particles, wolves, fireflies, magpies).
        n_trials: the trial budget T that t/T schedules refer to; past it they stay at their final value.
        seed: base seed; ``None`` draws one.
    """

    prefix: ClassVar[str]
    generational: ClassVar[bool] = False

    def __init__(self, *, population_size: int = 10, n_trials: int = 100, seed: int | None = None) -> None:
        if population_size < 2:
            raise ValueError(f"population_size must be >= 2, got {population_size}")
        if n_trials < 1:
            raise ValueError(f"n_trials must be >= 1, got {n_trials}")
        self.population_size = int(population_size)
        self.n_trials = int(n_trials)
        self._seed = int(np.random.SeedSequence().generate_state(1)[0]) if seed is None else int(seed)
        self._search_space = IntersectionSearchSpace()
        self._lock = threading.Lock()
        self._finished: dict[int, tuple] = {}  # trial id -> (trial object, (signature, sign), parsed member or None)
        self._replay: tuple | None = None  # (closed generations' key, Population) of the last replay

    # --- Optuna API -----------------------------------------------------------------------------------------

    def infer_relative_search_space(self, study: optuna.Study, trial: FrozenTrial) -> dict[str, BaseDistribution]:
        with self._lock:  # IntersectionSearchSpace keeps an incremental cache that threads must not interleave on
            space = self._search_space.calculate(study)
        return {name: d for name, d in space.items() if not d.single()}

    def sample_relative(self, study: optuna.Study, trial: FrozenTrial,
                        search_space: dict[str, BaseDistribution]) -> dict[str, Any]:
        self._raise_error_if_multi_objective(study)
        if not search_space:
            return {}
        space = dict(sorted(search_space.items()))
        transform = _SearchSpaceTransform(space, transform_0_1=True)
        signature = _signature(space)
        with self._lock:
            members = self._members(study, signature, transform.bounds.shape[0])
            ctx = self._context(members, trial.number, transform.bounds.shape[0], signature)
            move = self._propose(ctx)
            x = np.clip(np.asarray(move.x, dtype=float), 0.0, 1.0)
            attrs: dict[str, Any] = {"space": signature, "slot": ctx.slot, "gen": ctx.gen, "phase": move.phase}
            if move.v is not None:
                attrs["v"] = np.asarray(move.v, dtype=float).tolist()
            attrs["x"] = x.tolist()  # last: another process that sees x sees the whole record
            for key, value in attrs.items():
                study._storage.set_trial_system_attr(trial._trial_id, f"{self.prefix}:{key}", value)
        return transform.untransform(x)

    def sample_independent(self, study: optuna.Study, trial: FrozenTrial, param_name: str,
                           param_distribution: BaseDistribution) -> Any:
        self._raise_error_if_multi_objective(study)
        # RandomSampler's draw (uniform in the transformed space) from a per-(trial, parameter) stream.
        rng = np.random.default_rng([self._seed, trial.number, zlib.crc32(param_name.encode())])
        transform = _SearchSpaceTransform({param_name: param_distribution})
        return transform.untransform(rng.uniform(transform.bounds[:, 0], transform.bounds[:, 1]))[param_name]

    def reseed_rng(self) -> None:
        # Nothing to reseed: every trial's randomness is derived from (seed, trial number).
        pass

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_lock"]
        state["_finished"], state["_replay"] = {}, None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    # --- what subclasses implement ----------------------------------------------------------------------------

    @abc.abstractmethod
    def _propose(self, ctx: Context) -> Move:
        """The new trial's position (any real vector; it is clipped to the unit cube afterwards)."""

    def _replaces(self, new: Member, old_fitness: float) -> bool:
        """Generational only: whether ``new`` (finished, best of its slot in a closed generation) takes the slot."""
        return True

    # --- state rebuilt from storage ---------------------------------------------------------------------------

    def _members(self, study: optuna.Study, signature: str, dim: int) -> list[Member]:
        # Read past the per-thread trial cache so another thread's slot assignment is never missed.
        trials = study._get_trials(deepcopy=False, use_cache=False)
        sign = -1.0 if study.direction == StudyDirection.MAXIMIZE else 1.0
        key = f"{self.prefix}:"
        members = []
        for t in trials:
            # A finished trial never changes: its parsed form is kept while storage hands out the same object.
            cached = self._finished.get(t._trial_id)
            if cached is not None and cached[0] is t and cached[1] == (signature, sign):
                if cached[2] is not None:
                    members.append(cached[2])
                continue
            attrs = t.system_attrs
            member = None
            if attrs.get(key + "space") == signature and len(attrs.get(key + "x", ())) == dim:
                if t.state == TrialState.COMPLETE:
                    fitness = sign * float(t.value) if t.value is not None else np.inf
                elif t.state in (TrialState.FAIL, TrialState.PRUNED):
                    fitness = np.inf
                else:
                    fitness = None
                v = attrs.get(key + "v")
                member = Member(t.number, int(attrs[key + "slot"]), int(attrs[key + "gen"]), attrs[key + "phase"],
                                np.asarray(attrs[key + "x"], dtype=float),
                                None if v is None else np.asarray(v, dtype=float), fitness)
                members.append(member)
            if t.state.is_finished():
                self._finished[t._trial_id] = (t, (signature, sign), member)
        members.sort(key=lambda m: m.number)
        return members

    def _context(self, members: list[Member], number: int, dim: int, signature: str = "") -> Context:
        rng = np.random.default_rng([self._seed, number, 0])
        n = self.population_size
        if not self.generational:
            latest: dict[int, Member] = {}
            counts = [0] * n
            for m in members:
                if m.slot < n:
                    latest[m.slot] = m
                    counts[m.slot] += 1
            free = [s for s in range(n) if s not in latest or latest[s].finished]
            slot = min(free or range(n), key=lambda s: (counts[s], s))
            progress = min(1.0, len(members) / self.n_trials)
            return Context(members, slot, counts[slot], dim, rng, progress, None)

        gen = max((m.gen for m in members), default=0)
        current = [m for m in members if m.gen == gen]
        if sum(m.finished for m in current) >= n:
            gen, current = gen + 1, []
        taken = {m.slot for m in current}
        open_slots = [s for s in range(n) if s not in taken]
        if open_slots:
            slot = open_slots[0]
        else:
            waiting = [s for s in range(n) if not any(m.finished for m in current if m.slot == s)]
            slot = min(waiting, key=lambda s: (sum(m.slot == s for m in current), s))
        population = None
        if gen > 0:
            # The replay only changes when a trial of a closed generation is added or finishes.
            key = (signature, gen, tuple((m.number, m.fitness, m.x[0]) for m in members if m.gen < gen))
            if self._replay is None or self._replay[0] != key:
                self._replay = (key, self._population(members, gen, dim))
            population = self._replay[1]
        progress = min(1.0, gen * n / self.n_trials)
        return Context(members, slot, gen, dim, rng, progress, population)

    def _population(self, members: list[Member], gen: int, dim: int) -> Population:
        """Replay generations 0..gen-1 into the population that generation ``gen`` moves."""
        n = self.population_size
        first: dict[tuple[int, int], Member] = {}  # (generation, slot) -> first proposal
        done: dict[tuple[int, int], Member] = {}  # (generation, slot) -> best finished trial
        for m in members:
            if m.gen < gen and m.slot < n:
                cell = (m.gen, m.slot)
                first.setdefault(cell, m)
                if m.finished and (cell not in done or m.fitness < done[cell].fitness):
                    done[cell] = m
        x: list[np.ndarray | None] = [None] * n
        fitness = [np.inf] * n
        best_m: Member | None = None
        history = []
        for g in range(gen):
            for s in range(n):
                m = done.get((g, s))
                if m is not None:
                    if x[s] is None or self._replaces(m, fitness[s]):
                        x[s], fitness[s] = m.x, m.fitness
                    if m.fitness < (np.inf if best_m is None else best_m.fitness):
                        best_m = m
                elif x[s] is None and (g, s) in first:
                    x[s] = first[(g, s)].x  # never evaluated: keep the proposal, fitness stays +inf
            history.append(np.inf if best_m is None else best_m.fitness)
        # A slot never proposed in generation 0 only occurs in hand-made studies: park it at the centre.
        xs = np.array([np.full(dim, 0.5) if row is None else row for row in x])
        fs = np.array(fitness)
        if best_m is None:
            return Population(xs, fs, xs[int(np.argmin(fs))].copy(), np.inf, history)
        return Population(xs, fs, best_m.x, best_m.fitness, history)


def _signature(space: dict[str, BaseDistribution]) -> str:
    text = json.dumps({name: distribution_to_json(d) for name, d in space.items()}, sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:16]
