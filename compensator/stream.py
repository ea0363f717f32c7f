"""A table or a live feed through a compensator, one row at a time, into the values a controller accepts.

What ``thermodrift compensate`` does, as a library a controller-side program calls without the CLI:

1. :func:`open_rows` opens the input (CSV streamed line by line, ``-`` for stdin; Parquet and XLSX read whole)
   and refuses a table without a header or without a single row; :func:`read_probes` reads a probe file;
   :func:`check_writable` refuses an output whose folder does not exist. Every refusal is one
   :class:`~thermodrift.compensator.errors.InputError` naming the file, row and column, raised before anything
   is written.
2. :class:`Rows` finds the time column and the package's inputs in the header and turns each row of cells into
   (time in s, values in the units the model was trained in: ``value · scale + offset`` per input, the scale and
   offset from the manifest's units). An empty or non-numeric cell becomes NaN: a fault of that row that the
   guard holds or replaces (named in the audit), never interpolated and never a reason to stop.
3. :func:`run` feeds each row to the :class:`~thermodrift.compensator.guard.Compensator` and writes the
   controller format's rows (and an audit line per row); it returns the number of input rows.
"""

from __future__ import annotations

import csv
import datetime
import itertools
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Iterable, Iterator

import numpy as np

from thermodrift.compensator.errors import InputError
from thermodrift.compensator.guard import positive

PROBE_COLUMNS = ("time_s", "target", "um")


def open_rows(source: str) -> tuple[list[str], Iterator[list[Any]]]:
    """(header, rows as lists of cells) of ``source``; the iterator starts with the first row, which exists."""
    if source == "-":
        reader: Iterable[list[Any]] = csv.reader(sys.stdin)
    else:
        path = Path(source)
        if not path.is_file():
            raise InputError("input table not found", file=source, hint="check the path, or pass - for stdin")
        if path.suffix.lower() in (".parquet", ".xlsx"):
            import pandas as pd

            try:
                frame = pd.read_parquet(path) if path.suffix.lower() == ".parquet" else pd.read_excel(path)
            except Exception as exc:  # pyarrow and openpyxl raise their own errors for a damaged file
                raise InputError(f"unreadable ({type(exc).__name__})", file=source,
                                 hint="write the table again, or pass CSV") from None
            reader = iter([[str(c) for c in frame.columns], *frame.astype(object).to_numpy().tolist()])
        else:  # ',' or, from European exports, ';' or tabs: the header line tells which (as the recording loader)
            with open(path, newline="", encoding="utf-8-sig", errors="replace") as fh:
                first_line = fh.readline()
            reader = csv.reader(_lines(path), delimiter=max((",", ";", "\t"), key=first_line.count))
    reader = iter(reader)
    try:
        header = [str(c) for c in next(reader)]
        first = next(reader, None)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"not a CSV table ({type(exc).__name__})", file=source,
                         hint="pass a UTF-8 CSV, Parquet or XLSX table") from None
    except StopIteration:
        raise InputError("the input has no header row", file=source,
                         hint="the first line names the columns, as in the manifest") from None
    if first is None:
        raise InputError("the input has a header and no rows", file=source,
                         hint="pass a table with at least one row; nothing was written")
    return header, itertools.chain([first], _checked(reader, source))


def _lines(path: Path) -> Iterator[str]:
    with open(path, newline="", encoding="utf-8-sig") as fh:
        yield from fh


def _checked(reader: Iterable[list[Any]], source: str) -> Iterator[list[Any]]:
    """The rows after the first; a line that stops being text ends the stream with one line naming it."""
    row = 2
    try:
        for row, cells in enumerate(reader, start=3):
            yield cells
    except (UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"unreadable line ({type(exc).__name__})", file=source, row=row + 1,
                         hint="the rows before it were written") from None


def _seconds(cell: Any) -> float:
    """A time cell without a unit: a number (s), or an ISO timestamp as s since 1970 (UTC unless it says
    otherwise; only differences matter); NaN where unreadable."""
    t = _number(cell)
    if t == t:
        return t
    try:
        stamp = datetime.datetime.fromisoformat(str(cell).strip())
    except ValueError:
        return float("nan")
    return (stamp if stamp.tzinfo else stamp.replace(tzinfo=datetime.timezone.utc)).timestamp()


def _number(cell: Any) -> float:
    """A cell as a float; empty or non-numeric -> NaN (a fault of that row, handled downstream)."""
    try:
        return float(cell)
    except (TypeError, ValueError, OverflowError):
        return float("nan")


@dataclass
class Rows:
    """Cells -> (time s, input values in the model's units). ``convert``: input -> (scale, offset) to the
    canonical unit; ``time_scale_s``: seconds per unit of the time column (None: the manifest gives no time unit,
    so seconds or timestamps); ``run_column``: a column of run labels (None: one run), where a new label starts
    a new independent run (a cold start: :meth:`~thermodrift.compensator.guard.Compensator.new_run`)."""

    header: list[str]
    time_column: str
    time_scale_s: float | None
    inputs: list[str]
    convert: dict[str, tuple[float, float]]
    source: str = "-"
    run_column: str | None = None

    def __post_init__(self):
        where = {str(name).strip(): i for i, name in enumerate(self.header)}
        for column in [self.time_column, *self.inputs, *([self.run_column] if self.run_column else [])]:
            if column not in where:
                raise InputError("column not found in the input header", file=self.source, column=column,
                                 hint=f"the package reads {', '.join(self.inputs)} and the time column "
                                      f"{self.time_column!r}")
        self.t_idx = where[self.time_column]
        self.run_idx = where[self.run_column] if self.run_column else None
        self.idx = [where[c] for c in self.inputs]
        self.scale = np.array([self.convert[c][0] for c in self.inputs], dtype=float)
        self.offset = np.array([self.convert[c][1] for c in self.inputs], dtype=float)

    def run(self, cells: list[Any]) -> str | None:
        """The row's run label (None without a run column)."""
        if self.run_idx is None:
            return None
        return str(cells[self.run_idx]).strip() if self.run_idx < len(cells) else ""

    def parse(self, cells: list[Any]) -> tuple[float, np.ndarray]:
        """(time in s, or NaN where unreadable; the inputs, NaN for a missing or unreadable cell)."""
        n = len(cells)
        cell = cells[self.t_idx] if self.t_idx < n else ""
        t = _seconds(cell) if self.time_scale_s is None else _number(cell) * self.time_scale_s
        values = np.array([_number(cells[i]) if i < n else np.nan for i in self.idx]) * self.scale + self.offset
        return t, values


def read_probes(path: str, targets: list[str]) -> list[tuple[float, int, float]]:
    """Probe rows (``time_s``, ``target``, ``um``) as (time s, target index, µm); a missing column, an unknown
    target or a cell that is not a finite number is refused with its file, row and column."""
    if not Path(path).is_file():
        raise InputError("probe file not found", file=path, hint="a CSV with columns time_s, target, um")
    out = []
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = [c.strip() for c in next(reader, [])]
            for column in PROBE_COLUMNS:
                if column not in header:
                    raise InputError("column not found", file=path, column=column,
                                     hint="a probe file has columns time_s, target, um")
            at = [header.index(c) for c in PROBE_COLUMNS]
            for row, cells in enumerate(reader, start=2):
                if not any(c.strip() for c in cells):
                    continue
                t, target, um = (cells[i].strip() if i < len(cells) else "" for i in at)
                if target not in targets:
                    raise InputError(f"unknown target {target!r}", file=path, column="target", row=row,
                                     hint=f"the package's targets are {', '.join(targets)}")
                for column, text in (("time_s", t), ("um", um)):
                    if not np.isfinite(_number(text)):
                        raise InputError(f"{text!r} is not a finite number", file=path, column=column, row=row,
                                         hint="time in s, measured displacement in µm")
                out.append((float(t), targets.index(target), float(um)))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"not a CSV table ({type(exc).__name__})", file=path,
                         hint="a UTF-8 CSV with columns time_s, target, um") from None
    return out


def check_writable(path: str | None, what: str) -> None:
    """Refuse an output (``--out``, ``--audit``) whose folder does not exist or that names a folder."""
    if path is None or path == "-":
        return
    target = Path(path)
    if target.is_dir():
        raise InputError(f"the {what} names a folder", file=path, hint="give a file name")
    if not target.parent.is_dir():
        raise InputError(f"the folder of the {what} does not exist", file=path,
                         hint=f"create {target.parent} first; nothing was written")


def check_settings(settings: dict[str, tuple[float | None, str]], finite: tuple[str, ...] = ()) -> None:
    """Every setting (name -> (value, unit)) positive and finite (those in ``finite`` only finite); None is left
    to its default."""
    for name, (value, unit) in settings.items():
        if value is None:
            continue
        if name in finite:
            if not np.isfinite(_number(value)):
                raise InputError(f"{name} is {value!r}; it must be a finite number ({unit})")
        else:
            positive(name, value, unit)


def run(compensator, writer, rows: Iterable[list[Any]], parse: Rows, out: IO[str], audit=None,
        flush: bool = False) -> int:
    """Every row through ``compensator`` into ``out`` in ``writer``'s format (header first); an audit line per
    row when ``audit`` (:class:`~thermodrift.compensator.audit.Audit`) is given; ``flush`` after each row for a
    controller that reads values as they come. Returns the number of input rows."""
    table = csv.writer(out)
    table.writerow(writer.header())
    n, run = 0, None
    for cells in rows:
        label = parse.run(cells)
        if n and label != run:  # the next run (a cold start): the model and its checks start afresh
            compensator.new_run()
        run = label
        t, values = parse.parse(cells)
        step = compensator.update(t, values) if np.isfinite(t) else \
            compensator.hold_row(t, values, [("time", "time_unreadable")])
        table.writerows(writer.rows(step))
        if audit is not None:
            audit.write(step, values)
        if flush:
            out.flush()
        n += 1
    return n
