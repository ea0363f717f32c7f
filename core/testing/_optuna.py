"""Optuna helpers for the checks: studies that do not flood the log with one INFO line per trial."""

from __future__ import annotations

import contextlib
from typing import Iterator

import optuna


@contextlib.contextmanager
def quiet(level: int = optuna.logging.WARNING) -> Iterator[None]:
    """Optuna's log at ``level`` inside the block; the caller's verbosity is restored after it."""
    before = optuna.logging.get_verbosity()
    optuna.logging.set_verbosity(level)
    try:
        yield
    finally:
        optuna.logging.set_verbosity(before)
