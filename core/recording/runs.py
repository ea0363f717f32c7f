"""Recordings of several independent runs: a machine recorded day by day, each day a cold start.

A dataset may be several tables (files, or the sheets of one workbook with ``sheet: all``), or one table with a
``run:`` column (the manifest key names a column of labels; it may be the condition column): each table, sheet
or block of equal labels is one run. The runs are concatenated in the order given (files and sheets as listed,
blocks as they appear) into one :class:`Recording` whose ``runs()`` names each row's run; a run whose times do
not follow the previous run's is shifted to start one sampling interval after it, so time (s) increases through
the recording. Models with history start each run from its own first rows (``Recording.run_starts_s``).
"""

from __future__ import annotations

import glob
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import pandas as pd

from thermodrift.core.errors import InputError
from thermodrift.core.recording.types import TIME_INDEX, Channel, Recording

ALL_SHEETS = "all"  # manifest ``sheet: all``: every sheet of the workbook is one run


@dataclass
class Piece:
    """One run as loaded: its name, source table, times (s), canonical values per channel, channels, notes."""

    name: str
    source: str
    time_s: np.ndarray
    data: dict[str, Any]
    channels: dict[str, Channel]
    notes: list[str] = field(default_factory=list)


def table_paths(table_path: str | os.PathLike | Sequence[str | os.PathLike]) -> list[Path]:
    """The tables named by one path, a list of paths, or a glob pattern (matches sorted by name)."""
    if isinstance(table_path, (list, tuple)):
        if not table_path:
            raise InputError("no table given", hint="name at least one .csv, .parquet or .xlsx table")
        return [Path(p) for p in table_path]
    text = str(table_path)
    if any(ch in text for ch in "*?[") and not Path(text).exists():
        found = sorted(glob.glob(text))
        if not found:
            raise InputError("no table matches the pattern", file=text, hint="check the folder and the pattern")
        return [Path(p) for p in found]
    return [Path(table_path)]


def table_name(path: Path, sheet: str | None, tables: list[tuple[Path, str | None]]) -> str:
    """A run's name from its table: the file name without suffix, the sheet name for sheets of one workbook,
    or both when neither alone is unique."""
    paths = list(dict.fromkeys(p for p, _ in tables))
    if len(paths) == 1:
        return path.stem if sheet is None else str(sheet)
    stems = [p.stem for p in paths]
    base = path.stem if stems.count(path.stem) == 1 else str(path)
    return base if sum(p == path for p, _ in tables) == 1 else f"{base}:{sheet}"


def blocks(labels: np.ndarray, table: str, column: str, table_run: str, min_rows: int) -> list[tuple[str, int, int]]:
    """The runs of a ``run`` column: (name, first row, end row) per block of equal labels; each label one block
    of at least ``min_rows`` rows. Names are the labels (prefixed ``<table_run>/`` when several tables)."""
    starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
    ends = np.r_[starts[1:], len(labels)]
    seen: dict[str, int] = {}
    out = []
    for a, b in zip(starts, ends):
        label = str(labels[a])
        if label in seen:
            raise InputError(f"run {label!r} appears again after other runs (first from row {seen[label] + 2})",
                             file=table, column=column, row=int(a) + 2,
                             hint="sort the table by run, or give each run its own label")
        seen[label] = int(a)
        if b - a < min_rows:
            raise InputError(f"run {label!r} has only {b - a} rows; at least {min_rows} are needed", file=table,
                             column=column, row=int(a) + 2, hint="leave the run out or record it longer")
        out.append((label, int(a), int(b)))
    return out


def assemble(pieces: list[Piece]) -> Recording:
    """One :class:`Recording` of the runs ``pieces`` in order (see the module docstring)."""
    names = [p.name for p in pieces]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise InputError(f"two runs are named {dup!r}", file=pieces[names.index(dup)].source,
                         hint="give each run (file, sheet or run label) its own name")
    first = pieces[0]
    for piece in pieces[1:]:
        if list(piece.channels) != list(first.channels):
            lacks = [c for c in first.channels if c not in piece.channels]
            extra = [c for c in piece.channels if c not in first.channels]
            raise InputError(f"run {piece.name!r} has other channels than run {first.name!r} (missing "
                             f"{lacks or 'none'}, extra {extra or 'none'})", file=piece.source,
                             hint="record every run with the same channels and one manifest")
    times, notes, end, step = [], [], None, 0.0
    for piece in pieces:
        t = np.asarray(piece.time_s, dtype=float)
        if end is not None and t[0] <= end:
            t = t - t[0] + end + step
        step = float(np.median(np.diff(t))) if len(t) > 1 else step
        times.append(t)
        end = float(t[-1])
        notes += [n if n.startswith(piece.name) else f"{piece.name}: {n}" for n in piece.notes]
    frame = pd.DataFrame({c: np.concatenate([np.asarray(p.data[c]) for p in pieces]) for c in first.channels},
                         index=pd.Index(np.concatenate(times), name=TIME_INDEX))
    sources = list(dict.fromkeys(p.source for p in pieces))
    source = sources[0] if len(sources) == 1 else f"{sources[0]} and {len(sources) - 1} more"
    labels = np.concatenate([np.full(len(t), p.name, dtype=object) for p, t in zip(pieces, times)])
    return Recording(frame, first.channels, source=source, notes=notes, runs=labels)
