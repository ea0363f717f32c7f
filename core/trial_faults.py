"""A failed or diverged trial is one line on stderr; its traceback goes to the trial and a log file.

Optuna prints a full traceback for every failed trial; a study of 100 trials with 20 diverged networks
then buries the result. :func:`reporting` wraps an objective: on an exception it stores the traceback in the
trial's user attribute ``traceback`` (and the reason in ``fail_reason``), writes it to the
``thermodrift.trials`` logger (``thermodrift run`` sends that to ``trials.log`` in the job's output folder),
prints ``trial N failed: <reason>`` and re-raises so Optuna records the trial as FAIL.
"""

from __future__ import annotations

import functools
import logging
import sys
import traceback
from pathlib import Path
from typing import Callable

import optuna

LOGGER = logging.getLogger("thermodrift.trials")
LOGGER.setLevel(logging.INFO)
LOGGER.propagate = False  # tracebacks go to the log file only, not to the console handlers
MAX_TRACEBACK = 8000  # characters kept in the trial's attributes (the log file has all)


def reporting(objective: Callable[[optuna.Trial], float]) -> Callable[[optuna.Trial], float]:
    """``objective`` with failures reported as one line (see the module docstring)."""
    # Optuna's own warning for a failed trial carries the traceback; ours replaces it.
    logging.getLogger("optuna.study._optimize").setLevel(logging.ERROR)

    @functools.wraps(objective)
    def wrapped(trial: optuna.Trial) -> float:
        try:
            return objective(trial)
        except optuna.TrialPruned:
            raise
        except Exception as exc:
            text = traceback.format_exc()
            reason = trial.user_attrs.get("fail_reason") or " ".join(f"{type(exc).__name__}: {exc}".split())
            trial.set_user_attr("fail_reason", reason[:1000])
            trial.set_user_attr("traceback", text[-MAX_TRACEBACK:])
            LOGGER.info("trial %d failed: %s\n%s", trial.number, reason, text)
            print(f"thermodrift: trial {trial.number} failed: {reason[:300]}", file=sys.stderr)
            raise
    return wrapped


def log_to(folder: str | Path) -> Path:
    """Send trial tracebacks to ``folder/trials.log`` (in addition to any earlier file); return its path."""
    path = Path(folder) / "trials.log"
    path.parent.mkdir(parents=True, exist_ok=True)
    if not any(isinstance(h, logging.FileHandler) and Path(h.baseFilename) == path.resolve()
               for h in LOGGER.handlers):
        handler = logging.FileHandler(path, encoding="utf-8", delay=True)
        handler.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
        LOGGER.addHandler(handler)
    return path
