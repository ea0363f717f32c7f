"""The safe update: input checks, holds and fallbacks, probe bias, rate limit and clamp around a runtime.

Per row (values in the package's input order, time in s):

1. Input checks (every row): a missing value (NaN), a value outside the training range by more than the
   package's margin, a sensor stuck at one value for longer than training ever showed, a jump faster than the
   training steps allow (measured from the last good value, so one spike fails one row). A time that does not
   increase fails the whole row; a gap longer than the sampling interval is noted.
2. The model is fed the row with each failed value replaced by that sensor's last good value, so its state
   stays finite; that prediction is reported (``raw``) but never written while an input has failed. Instead,
   with one failed sensor and a fallback model fitted without it, the fallback's prediction is used
   (``fallback``); otherwise the last written value is held (``held``; 0 µm before anything was written).
3. The probe bias (if any) is added; then the change per update is limited (``rate_limited``) and the value is
   clamped (``clamped``). A row's status per target is the most severe that applied:
   held/fallback > clamped > rate_limited > ok.

``limits=False`` writes the model's own prediction (plus the probe bias, if probes are given) and only reports,
in the statuses and faults, what would have applied.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from thermodrift.compensator import runtime
from thermodrift.compensator.errors import InputError
from thermodrift.compensator.probe import BiasFilter

STATUSES = ("ok", "rate_limited", "clamped", "held", "fallback")
OK, RATE_LIMITED, CLAMPED, HELD, FALLBACK = range(5)


@dataclass
class Step:
    """One update's outcome: µm per target, status codes (indices into :data:`STATUSES`), and the faults found
    as (sensor or "time", reason)."""

    time_s: float
    written: np.ndarray
    raw: np.ndarray
    status: np.ndarray
    faults: list[tuple[str, str]] = field(default_factory=list)
    bias: np.ndarray | None = None
    source: str = "model"  # "model", "fallback:<sensor>" or "hold"


class Compensator:
    """Wraps a package's runtime for controller use (see the module docstring).

    ``max_step_um`` / ``clamp_um``: one number for every target, or None for the package's per-target defaults;
    ``probes``: (time s, target index, measured µm) tuples in any order.
    """

    def __init__(self, package, max_step_um: float | None = None, clamp_um: float | None = None,
                 limits: bool = True, probes: list[tuple[float, int, float]] | None = None,
                 history: np.ndarray | None = None, history_times_s: np.ndarray | None = None):
        self.package = package
        for name, value in (("max_step_um", max_step_um), ("clamp_um", clamp_um)):
            if value is not None:
                positive(name, value, "µm")
        safety = package.safety
        ins, tg = package.inputs, package.targets
        self.limits = limits
        self.max_step = (np.full(len(tg), float(max_step_um)) if max_step_um is not None
                         else np.array([safety["max_step_um"][t] for t in tg], dtype=float))
        self.clamp = (np.full(len(tg), float(clamp_um)) if clamp_um is not None
                      else np.array([safety["clamp_um"][t] for t in tg], dtype=float))
        self.low = np.array([safety["input_low"][c] for c in ins], dtype=float)
        self.high = np.array([safety["input_high"][c] for c in ins], dtype=float)
        self.jump = np.array([safety["jump"][c] for c in ins], dtype=float)
        self.stuck = np.array([safety["stuck_samples"][c] for c in ins], dtype=float)
        self.gap_s = safety["time_gap_factor"] * package.sampling_interval_s
        self.model = package.runtime.streamer(history, history_times_s)
        self.fallbacks = package.fallbacks  # sensor -> {"state", "warmup_rows"}
        self._fb_runtimes: dict[str, tuple[object, np.ndarray]] = {}  # sensor -> (runtime, its input positions)
        self._fb: tuple[str, object] | None = None  # the fallback in use: (sensor, streamer)
        warm = max([int(f.get("warmup_rows", 0)) for f in self.fallbacks.values()] or [0])
        self.buffer: deque = deque(maxlen=max(warm, 1))  # recent model rows (failed values replaced)
        if self.fallbacks and history is not None:  # a fallback switched in at the first row warms on history
            times = history_times_s if history_times_s is not None else np.arange(len(history), dtype=float)
            self.buffer.extend(zip(np.asarray(times, dtype=float), np.asarray(history, dtype=float)))
        mid = np.array([(package.limits["inputs"][c]["min"] + package.limits["inputs"][c]["max"]) / 2 for c in ins])
        self.last_good = mid  # until a sensor reads well once, its training mid-range stands in
        self.jump_allow = self.jump.copy()  # a failed row widens the allowed jump by one training step more
        self.any_bad = False
        self.prev_values: np.ndarray | None = None
        self.same = np.zeros(len(ins))
        self.t_prev: float | None = None
        self.prev_written: np.ndarray | None = None
        self.bias = BiasFilter(len(tg), **package.probe) if probes else None
        self.probes = sorted(probes or [])
        self._next_probe = 0

    def new_run(self) -> None:
        """Start a new independent run (a cold start, e.g. the next working day): the model's state, the input
        checks' memory, the last written value and the probe bias start afresh, as in a new compensator."""
        ins, tg = self.package.inputs, self.package.targets
        self.model = self.package.runtime.streamer()
        self._fb = None
        self.buffer.clear()
        self.last_good = np.array([(self.package.limits["inputs"][c]["min"] + self.package.limits["inputs"][c]["max"])
                                   / 2 for c in ins])
        self.jump_allow, self.any_bad, self.prev_values = self.jump.copy(), False, None
        self.same, self.t_prev, self.prev_written = np.zeros(len(ins)), None, None
        if self.bias is not None:
            self.bias = BiasFilter(len(tg), **self.package.probe)

    # --------------------------------------------------------------------------------------------- checks
    def check(self, values: np.ndarray) -> np.ndarray | None:
        """None when every input passes; else a reason code per input: 0 good, 1 missing, 2 out of range,
        3 stuck, 4 jump. (Comparisons with NaN are false, so the in-range test also fails a missing value.)"""
        passed = (values >= self.low) & (values <= self.high)
        have_prev = self.prev_values is not None
        if have_prev:
            self.same = np.where(values == self.prev_values, self.same + 1.0, 0.0)
            passed &= (self.same < self.stuck) & (np.abs(values - self.last_good) <= self.jump_allow)
        self.prev_values = values
        if np.count_nonzero(passed) == len(passed):  # count_nonzero: one C call, cheaper than .all()
            return None
        code = np.where(passed, 0, 2).astype(np.int8)
        if have_prev:
            code[self.same >= self.stuck] = 3
            code[~(np.abs(values - self.last_good) <= self.jump_allow) & ~np.isnan(values)] = 4
        code[(values < self.low) | (values > self.high)] = 2
        code[np.isnan(values)] = 1
        return code

    def update(self, t_s: float, values: np.ndarray) -> Step:
        """Process one row (see the module docstring)."""
        values = np.asarray(values, dtype=float)
        faults: list[tuple[str, str]] = []
        if self.t_prev is not None:
            if not t_s > self.t_prev:
                return self.hold_row(t_s, values, [("time", "time_not_increasing")])
            if t_s - self.t_prev > self.gap_s:
                faults.append(("time", "time_gap"))
        self.t_prev = t_s
        code = self.check(values)
        if code is None:  # the common case: every input passed
            raw = self.model.update(values, t_s)
            if self.any_bad:
                self.jump_allow, self.any_bad, self._fb = self.jump.copy(), False, None
            self.last_good = values
            base, source, model_out = OK, "model", raw
        else:
            bad = code > 0
            ins = self.package.inputs
            faults += [(ins[i], REASONS[code[i]]) for i in np.flatnonzero(bad)]
            fed = np.where(bad, self.last_good, values) if self.limits else values
            raw = self.model.update(fed, t_s)
            self.jump_allow = np.where(bad, self.jump_allow + self.jump, self.jump)
            self.last_good = np.where(bad, self.last_good, values)
            self.any_bad = True
            model_out = self._fallback(int(np.flatnonzero(bad)[0]), t_s, fed) if int(bad.sum()) == 1 else None
            base, source = (FALLBACK, f"fallback:{self._fb[0]}") if model_out is not None else (HELD, "hold")
            values = fed
        if self.fallbacks:
            self.buffer.append((t_s, values))
        bias = self._probe(t_s, model_out) if self.bias is not None else None
        if not self.limits:
            written = raw if bias is None else raw + bias
            return self._limit(t_s, written, raw, base, faults, bias, source, apply=False)
        if base == HELD:
            target = self.prev_written if self.prev_written is not None else np.zeros_like(raw)
        else:
            target = model_out if bias is None else model_out + bias
        return self._limit(t_s, target, raw, base, faults, bias, source, apply=True)

    # --------------------------------------------------------------------------------------------- parts
    def _limit(self, t_s, target, raw, base, faults, bias, source, apply: bool) -> Step:
        status = np.full(len(target), base, dtype=np.int8)
        value = target
        if self.prev_written is not None:
            delta = target - self.prev_written
            over = np.abs(delta) > self.max_step
            if np.count_nonzero(over):
                status[over & (status < RATE_LIMITED)] = RATE_LIMITED
                if apply:
                    value = self.prev_written + np.clip(delta, -self.max_step, self.max_step)
        out = np.abs(value) > self.clamp
        if np.count_nonzero(out):
            status[out & (status < CLAMPED)] = CLAMPED
            if apply:
                value = np.clip(value, -self.clamp, self.clamp)
        if apply and not np.isfinite(value.sum()):  # never write a non-finite value
            held = self.prev_written if self.prev_written is not None else np.zeros_like(value)
            bad = ~np.isfinite(value)
            value = np.where(bad, held, value)
            status[bad] = HELD
        self.prev_written = value
        return Step(t_s, value, raw, status, faults, bias, source)

    def hold_row(self, t_s: float, values: np.ndarray, faults) -> Step:
        """A row that cannot be used at all: the model is not stepped; the last written value stays."""
        held = self.prev_written if self.prev_written is not None else np.zeros(len(self.package.targets))
        nan = np.full(len(held), np.nan)
        return Step(t_s, held, nan, np.full(len(held), HELD, dtype=np.int8), faults, None, "hold")

    def _fallback(self, i: int, t_s: float, fed: np.ndarray):
        """The prediction of the fallback fitted without input ``i`` (None where the package has none)."""
        sensor = self.package.inputs[i]
        spec = self.fallbacks.get(sensor)
        if spec is None:
            self._fb = None
            return None
        if sensor not in self._fb_runtimes:
            rt = runtime.build(spec["state"])
            self._fb_runtimes[sensor] = rt, np.array([self.package.inputs.index(c) for c in rt.inputs], dtype=int)
        rt, idx = self._fb_runtimes[sensor]
        if self._fb is None or self._fb[0] != sensor:  # warm a fresh one on the recent rows
            rows = list(self.buffer)
            history = np.array([r[1][idx] for r in rows]) if rows else None
            times = np.array([r[0] for r in rows]) if rows else None
            self._fb = (sensor, rt.streamer(history, times))
        return self._fb[1].update(fed[idx], t_s)

    def _probe(self, t_s: float, model_out) -> np.ndarray:
        self.bias.advance(t_s)
        while self._next_probe < len(self.probes) and self.probes[self._next_probe][0] <= t_s:
            _, target, measured = self.probes[self._next_probe]
            self._next_probe += 1
            if model_out is not None and np.isfinite(measured):
                self.bias.correct(int(target), float(measured) - float(model_out[int(target)]))
        return self.bias.b.copy()


REASONS = ("ok", "missing", "out_of_range", "stuck", "jump")


def positive(name: str, value, unit: str) -> float:
    """``value`` as a float if it is finite and above zero; else :class:`InputError` naming the option ``name``
    (a negative rate limit or clamp would write nonsense to a machine)."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = float("nan")
    if not (np.isfinite(number) and number > 0):
        raise InputError(f"{name} is {value!r}; it must be a positive finite number ({unit})",
                         hint="leave it out for the package's default" if name in ("max_step_um", "clamp_um")
                         else None)
    return number
