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
   scale-free. A parameter whose range changes leaves the intersection and is then sampled independently.
2. Read this space's members from storage: the trials carrying ``<prefix>:space`` equal to the space's signature
   (trials of another space are ignored: a changed space starts a new population). Fitness is the value, negated
   when maximising; FAIL and PRUNED count as +inf (worst); RUNNING and WAITING are pending.
   The first trial of a study is drawn before any search space exists (Optuna knows none until a trial has
   finished), so it cannot carry a position; such *adopted* trials -- numbers below N, not proposed by this
   sampler (the first trial, enqueued trials), finished with every parameter of the space -- join the
   population as slot = trial number, generation 0, phase ``init``, at the position of their parameters. While
   such a trial runs, it holds its slot.
   A finished trial never changes, so it is read once and folded into running aggregates (per-slot latest and
   best, the finished members ranked by fitness, members per generation, and the replayed population after each
   closed generation); an ask re-reads only the trials that were unfinished or new since the last one, so its
   cost hardly grows with the size of the study.
3. Give the new trial a slot 0..N-1 and a generation, and claim that cell through the storage (below).
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
read the budget ``n_trials`` given at construction (the study passes its own).

Several OS processes or machines may share one RDB study: each reads the others' trials from storage. Two of them
asking at the same instant read the same state and would pick the same cell (generation, slot), so a cell is
claimed before it is used: the claim is a study system attribute ``<prefix>:claim:<space>:<gen>:<slot>:<k>``
(``k`` counts the cell's earlier trials, re-proposals of generational algorithms) whose value is the claiming
trial's id. On an RDB storage (SQLite, PostgreSQL, MySQL) the claim is a plain INSERT into Optuna's
``study_system_attributes`` table, whose unique (study, key) constraint lets exactly one worker win; Optuna's own
``set_study_system_attr`` overwrites, so it cannot serve. In memory the claim is made under the storage's lock.
Other storages (journal, gRPC proxy) get a check-then-write claim that narrows the race without closing it. A
worker that loses a claim treats the cell as taken by a pending trial it cannot see yet (or, when the winner's
trial has already ended without a record, as used), re-reads the storage and picks again, so no cell goes to two
workers while the population state stays in storage and a resumed run still continues the same sequence.
"""

from __future__ import annotations

import abc
import bisect
import hashlib
import json
import threading
import zlib
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, ClassVar, Sequence

import numpy as np
import optuna
import sqlalchemy.exc
from optuna._transform import _SearchSpaceTransform  # Optuna's own encoder, shared with its CMA-ES and GP samplers
from optuna.distributions import BaseDistribution, distribution_to_json
from optuna.samplers import BaseSampler
from optuna.storages import BaseStorage, InMemoryStorage, RDBStorage
from optuna.storages._rdb import models as rdb_models  # the claim's INSERT needs the table Optuna's RDB schema defines
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

    slot: int
    gen: int
    dim: int
    rng: np.random.Generator
    progress: float  # share of the budget n_trials used before this trial (generational: before its generation)
    population: Population | None  # generational algorithms, gen >= 1
    latest: Member | None  # this slot's latest trial (asynchronous algorithms)
    own_best: Member | None  # this slot's best finished trial with finite fitness
    ranked: Sequence[Member]  # every finished member with finite fitness, best first (ties: earlier trial first)


@dataclass(frozen=True)
class Move:
    """A proposal: position in the unit cube, the phase that produced it, and the velocity if any."""

    x: np.ndarray
    phase: str
    v: np.ndarray | None = None


def _rank_key(m: Member) -> tuple[float, int]:
    return m.fitness, m.number


@dataclass(frozen=True)
class _Replayed:
    """The replay state before some generation: per-slot position and fitness, best member, best history."""

    x: tuple[np.ndarray | None, ...]
    fitness: tuple[float, ...]
    best: Member | None
    history: tuple[float, ...]


@dataclass
class _Ledger:
    """What one sampler has read of one population (study, search space, direction), folded in incrementally."""

    storage: Any
    seen: int = 0  # trials[:seen] have been read
    open: list[int] = field(default_factory=list)  # numbers below ``seen`` that were unfinished when last read
    count: int = 0  # finished members folded in
    slot_count: defaultdict = field(default_factory=lambda: defaultdict(int))
    slot_latest: dict[int, Member] = field(default_factory=dict)  # finished, highest number per slot
    slot_best: dict[int, Member] = field(default_factory=dict)  # finished with finite fitness, best per slot
    ranked: list[Member] = field(default_factory=list)  # finished with finite fitness, by (fitness, number)
    by_gen: defaultdict = field(default_factory=lambda: defaultdict(list))  # generation -> finished members
    max_gen: int = -1
    replays: list[_Replayed] = field(default_factory=list)  # [g]: state before generation g, finished members only

    def fold(self, m: Member) -> None:
        """Add a finished member to every aggregate."""
        self.count += 1
        self.slot_count[m.slot] += 1
        if m.slot not in self.slot_latest or m.number > self.slot_latest[m.slot].number:
            self.slot_latest[m.slot] = m
        if m.fitness < np.inf:
            if m.slot not in self.slot_best or _rank_key(m) < _rank_key(self.slot_best[m.slot]):
                self.slot_best[m.slot] = m
            bisect.insort(self.ranked, m, key=_rank_key)
        self.by_gen[m.gen].append(m)
        self.max_gen = max(self.max_gen, m.gen)
        del self.replays[m.gen + 1:]  # replays after generation m.gen change


class PopulationSampler(BaseSampler, abc.ABC):
    """Base of population metaheuristics as Optuna samplers: a subclass writes only the algorithm's move.

    A subclass (one file; ``docs/templates/optimizer_plugin.py`` is a complete example):

    * sets ``prefix`` (a short name; its trial attributes are stored as ``<prefix>:slot`` and the like) and,
      for an algorithm that moves the whole population once per generation, ``generational = True``;
    * implements ``_propose(ctx: Context) -> Move``: the position in the unit cube [0, 1]^D of the trial in
      slot ``ctx.slot``, drawing every random number from ``ctx.rng``. :class:`Context` gives ``dim`` (D),
      ``progress`` (t/T in [0, 1]), ``latest`` and ``own_best`` (this slot's latest and best :class:`Member`,
      asynchronous algorithms), ``ranked`` (every finished member with finite fitness, best first) and
      ``population`` (generational algorithms, from generation 1: the :class:`Population` after the last
      closed generation). :class:`Move` holds ``x``, a ``phase`` label and an optional velocity ``v``;
    * may override ``_replaces(new, old_fitness) -> bool`` (generational: whether the best new member of a
      slot replaces it; default: always, ``new.fitness < old_fitness`` is greedy selection);
    * may add constructor settings after the base's keyword-only ``population_size``, ``n_trials`` and
      ``seed`` (store each unchanged and pass the three on), and a ``get_test_params()`` classmethod.

    The base encodes every distribution (float, log, step, int, categorical) into the unit cube, keeps the
    population in the study's storage (threads, processes and resumed runs share it), treats FAIL and PRUNED
    trials as worst fitness, adopts enqueued trials and the study's first trial into the population, draws
    parameters outside the common search space as Optuna's RandomSampler does, and makes one seed give one
    trial sequence. The module docstring has the details.

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
        self._ledgers: dict[tuple, _Ledger] = {}  # (study id, space signature, sign) -> what was read of it

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
            lost: dict[tuple[int, int, int], bool] = {}  # cells other trials claimed -> whether that trial runs
            while True:
                ledger, pending = self._read(study, space, transform, trial.number)
                ctx, k = self._context(ledger, pending, trial.number, transform.bounds.shape[0], lost)
                owner = _claim(study._storage, study._study_id,
                               f"{self.prefix}:claim:{signature}:{ctx.gen}:{ctx.slot}:{k}", trial._trial_id)
                if owner is None:
                    break
                # Each loss adds a new cell that _context never returns again, so this ends.
                lost[(ctx.gen, ctx.slot, k)] = not study._storage.get_trial(owner).state.is_finished()
            move = self._propose(ctx)
            x = np.clip(np.asarray(move.x, dtype=float), 0.0, 1.0)
            attrs: dict[str, Any] = {"space": signature, "slot": ctx.slot, "gen": ctx.gen,
                                     "phase": move.phase}
            if move.v is not None:
                attrs["v"] = np.asarray(move.v, dtype=float).tolist()
            attrs["x"] = x.tolist()  # last: another process that sees x sees the whole record
            for key, value in attrs.items():
                study._storage.set_trial_system_attr(trial._trial_id, f"{self.prefix}:{key}", value)
        # Optuna's decoder returns numpy scalars for values clipped to a bound; trial parameters are plain Python.
        return {name: v.item() if isinstance(v, np.generic) else v for name, v in transform.untransform(x).items()}

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
        state["_ledgers"] = {}
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    # --- inspection ---------------------------------------------------------------------------------------------

    def members(self, study: optuna.Study) -> list[Member]:
        """The members of the study's current relative search space, by trial number."""
        space, transform = self._current_space(study)
        with self._lock:
            return self._all_members(*self._read(study, space, transform, None))

    def population(self, study: optuna.Study, gen: int) -> Population:
        """The population that generation ``gen`` (>= 1) of a generational algorithm moves, replayed in full."""
        members = self.members(study)
        if not members:
            raise ValueError("the study has no members of its current search space yet")
        return self._replay(members, gen, len(members[0].x))

    def _current_space(self, study: optuna.Study) -> tuple[dict[str, BaseDistribution], _SearchSpaceTransform]:
        space = dict(sorted(self.infer_relative_search_space(study, None).items()))
        return space, _SearchSpaceTransform(space, transform_0_1=True)

    # --- what subclasses implement ----------------------------------------------------------------------------

    @abc.abstractmethod
    def _propose(self, ctx: Context) -> Move:
        """The new trial's position (any real vector; it is clipped to the unit cube afterwards)."""

    def _replaces(self, new: Member, old_fitness: float) -> bool:
        """Generational only: whether ``new`` (finished, best of its slot in a closed generation) takes the slot."""
        return True

    # --- state read from storage ------------------------------------------------------------------------------

    def _read(self, study: optuna.Study, space: dict[str, BaseDistribution], transform: _SearchSpaceTransform,
              asking: int | None) -> tuple[_Ledger, list[Member]]:
        """Fold the trials that finished since the last read into this population's ledger; return it with the
        pending members (trial ``asking``, the one being sampled, left out)."""
        signature = _signature(space)
        sign = -1.0 if study.direction == StudyDirection.MAXIMIZE else 1.0
        key = (study._study_id, signature, sign)
        ledger = self._ledgers.get(key)
        if ledger is None or ledger.storage is not study._storage:
            ledger = self._ledgers[key] = _Ledger(study._storage)
        # Read past the per-thread trial cache so another thread's slot assignment is never missed.
        trials = study._get_trials(deepcopy=False, use_cache=False)
        still_open, pending = [], []
        for number in ledger.open + list(range(ledger.seen, len(trials))):
            t = trials[number]
            if t.number == asking:
                still_open.append(number)
                continue
            member = self._parse(t, space, signature, sign, transform)
            if t.state.is_finished():
                if member is not None:
                    ledger.fold(member)
            else:
                still_open.append(number)
                if member is not None:
                    pending.append(member)
        ledger.open, ledger.seen = still_open, len(trials)
        return ledger, pending

    def _parse(self, t: FrozenTrial, space: dict[str, BaseDistribution], signature: str, sign: float,
               transform: _SearchSpaceTransform) -> Member | None:
        """Trial ``t`` as a member of this space's population, or None."""
        if t.state == TrialState.COMPLETE:
            fitness = sign * float(t.value) if t.value is not None else np.inf
        elif t.state in (TrialState.FAIL, TrialState.PRUNED):
            fitness = np.inf
        else:
            fitness = None
        attrs, key = t.system_attrs, f"{self.prefix}:"
        if key + "space" in attrs:
            if attrs[key + "space"] != signature or len(attrs.get(key + "x", ())) != transform.bounds.shape[0]:
                return None
            v = attrs.get(key + "v")
            return Member(t.number, int(attrs[key + "slot"]), int(attrs[key + "gen"]), attrs[key + "phase"],
                          np.asarray(attrs[key + "x"], dtype=float),
                          None if v is None else np.asarray(v, dtype=float), fitness)
        if t.number >= self.population_size or any(t.distributions.get(n) != d for n, d in space.items()):
            return None
        # Adopted (a trial this sampler did not propose, with every parameter of the space); while it runs it is
        # pending and holds its slot.
        x = np.clip(transform.transform({name: t.params[name] for name in space}), 0.0, 1.0)
        return Member(t.number, t.number, 0, "init", x, None, fitness)

    def _context(self, ledger: _Ledger, pending: list[Member], number: int, dim: int,
                 lost: dict[tuple[int, int, int], bool] | None = None) -> tuple[Context, int]:
        """The new trial's context and ``k``, the number of earlier trials in its cell (generation, slot).
        ``lost`` maps the cells (gen, slot, k) that other trials claimed to whether their trial still runs; their
        records may not be readable yet, so they count as trials of that cell here."""
        rng = np.random.default_rng([self._seed, number, 0])
        n = self.population_size
        ranked = ledger.ranked
        lost = {(g, s, k): running for (g, s, k), running in (lost or {}).items() if s < n}
        if not self.generational:
            counts = [ledger.slot_count[s] for s in range(n)]
            latest = {s: m for s, m in ledger.slot_latest.items() if s < n}
            for m in pending:
                if m.slot < n:
                    counts[m.slot] += 1
                    if m.slot not in latest or m.number > latest[m.slot].number:
                        latest[m.slot] = m
            busy = set()
            for (g, s, _), running in lost.items():  # an asynchronous slot's gen counts its moves
                counts[s] = max(counts[s], g + 1)
                if running:
                    busy.add(s)
            free = [s for s in range(n) if s not in busy and (s not in latest or latest[s].finished)]
            slot = min(free or range(n), key=lambda s: (counts[s], s))
            progress = min(1.0, (ledger.count + len(pending)) / self.n_trials)
            return Context(slot, counts[slot], dim, rng, progress, None, latest.get(slot), ledger.slot_best.get(slot),
                           ranked), 0

        gen = max(0, ledger.max_gen, *(m.gen for m in pending))
        current = ledger.by_gen.get(gen, []) + [m for m in pending if m.gen == gen]
        if sum(m.finished for m in current) >= n:
            gen, current = gen + 1, []
        tried = [sum(m.slot == s for m in current) for s in range(n)]  # trials per cell of this generation
        for (g, s, k) in lost:
            if g == gen:
                tried[s] = max(tried[s], k + 1)
        open_slots = [s for s in range(n) if tried[s] == 0]
        if open_slots:
            slot = open_slots[0]
        else:
            waiting = [s for s in range(n) if not any(m.finished for m in current if m.slot == s)]
            slot = min(waiting, key=lambda s: (tried[s], s))
        population = None
        if gen > 0:
            if any(m.gen < gen for m in pending):  # a straggler of a closed generation: replay everything
                population = self._replay(self._all_members(ledger, pending), gen, dim)
            else:
                population = self._population_of(ledger, gen, dim)
        progress = min(1.0, gen * n / self.n_trials)
        return Context(slot, gen, dim, rng, progress, population, None, ledger.slot_best.get(slot), ranked), tried[slot]

    # --- the generational replay --------------------------------------------------------------------------------

    def _population_of(self, ledger: _Ledger, gen: int, dim: int) -> Population:
        """The population generation ``gen`` moves, continued from the ledger's replays of finished members."""
        if not ledger.replays:
            ledger.replays.append(self._before_generation_0())
        while len(ledger.replays) <= gen:
            g = len(ledger.replays) - 1
            cohort = sorted(ledger.by_gen.get(g, []), key=lambda m: m.number)
            ledger.replays.append(self._step(ledger.replays[g], cohort))
        return self._as_population(ledger.replays[gen], dim)

    def _replay(self, members: list[Member], gen: int, dim: int) -> Population:
        """Replay generations 0..gen-1 of ``members`` (by trial number, pending included) into the population of
        ``gen``."""
        state = self._before_generation_0()
        by_gen = defaultdict(list)
        for m in members:
            by_gen[m.gen].append(m)
        for g in range(gen):
            state = self._step(state, by_gen.get(g, []))
        return self._as_population(state, dim)

    def _before_generation_0(self) -> _Replayed:
        return _Replayed((None,) * self.population_size, (np.inf,) * self.population_size, None, ())

    def _step(self, state: _Replayed, cohort: list[Member]) -> _Replayed:
        """Apply one closed generation (its members by trial number) to the replay state."""
        n = self.population_size
        first: dict[int, Member] = {}  # slot -> first proposal
        done: dict[int, Member] = {}  # slot -> best finished trial
        for m in cohort:
            if m.slot < n:
                first.setdefault(m.slot, m)
                if m.finished and (m.slot not in done or m.fitness < done[m.slot].fitness):
                    done[m.slot] = m
        x, fitness, best_m = list(state.x), list(state.fitness), state.best
        for s in range(n):
            m = done.get(s)
            if m is not None:
                if x[s] is None or self._replaces(m, fitness[s]):
                    x[s], fitness[s] = m.x, m.fitness
                if m.fitness < (np.inf if best_m is None else best_m.fitness):
                    best_m = m
            elif x[s] is None and s in first:
                x[s] = first[s].x  # never evaluated: keep the proposal, fitness stays +inf
        return _Replayed(tuple(x), tuple(fitness), best_m,
                         state.history + (np.inf if best_m is None else best_m.fitness,))

    @staticmethod
    def _as_population(state: _Replayed, dim: int) -> Population:
        # A slot never proposed in generation 0 only occurs in hand-made studies: park it at the centre.
        xs = np.array([np.full(dim, 0.5) if row is None else row for row in state.x])
        fs = np.array(state.fitness)
        history = list(state.history)
        if state.best is None:
            return Population(xs, fs, xs[int(np.argmin(fs))].copy(), np.inf, history)
        return Population(xs, fs, state.best.x, state.best.fitness, history)

    @staticmethod
    def _all_members(ledger: _Ledger, pending: list[Member]) -> list[Member]:
        folded = [m for cohort in ledger.by_gen.values() for m in cohort]
        return sorted(folded + pending, key=lambda m: m.number)


def _claim(storage: BaseStorage, study_id: int, key: str, trial_id: int) -> int | None:
    """Claim ``key`` of study ``study_id`` for trial ``trial_id``: None when this trial now holds it, else the id
    of the trial that does. Exactly one claimant wins on RDB and in-memory storages (module docstring)."""
    backend = getattr(storage, "_backend", storage)  # optuna.create_study wraps an RDBStorage in a cache
    if isinstance(backend, RDBStorage):
        # A plain INSERT: the table's unique (study_id, key) makes every claimant but the first fail.
        session = backend.scoped_session()
        try:
            session.add(rdb_models.StudySystemAttributeModel(study_id=study_id, key=key,
                                                             value_json=json.dumps(trial_id)))
            session.commit()
            return None
        except sqlalchemy.exc.IntegrityError:
            session.rollback()
            value = session.query(rdb_models.StudySystemAttributeModel.value_json).filter_by(
                study_id=study_id, key=key).scalar()
            return int(json.loads(value))
        finally:
            session.close()
    if isinstance(backend, InMemoryStorage):
        with backend._lock:  # the lock every InMemoryStorage method holds
            return _check_then_write(backend, study_id, key, trial_id)
    return _check_then_write(backend, study_id, key, trial_id)


def _check_then_write(storage: BaseStorage, study_id: int, key: str, trial_id: int) -> int | None:
    owner = storage.get_study_system_attrs(study_id).get(key)
    if owner is not None:
        return int(owner)
    storage.set_study_system_attr(study_id, key, trial_id)
    return None


def _signature(space: dict[str, BaseDistribution]) -> str:
    text = json.dumps({name: distribution_to_json(d) for name, d in space.items()}, sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:16]
