"""Loading a table (CSV, Parquet or XLSX) and its YAML manifest into a :class:`Recording`, with validation.

A manifest names the time column and gives every used column a role and a unit::

    time: time_s                 # seconds; or time_unit: s|ms|min|h; or timestamps (converted to s from start)
    sheet: data                  # XLSX only; default: the first sheet
    channels:
      spindle_rpm: {role: speed, unit: rpm}
      T_front_bearing: {role: temperature, unit: degC, location: front_bearing}
      disp_z_um: {role: displacement, unit: um, axis: z}

:func:`load_recording` checks everything a user can get wrong and raises :class:`InputError` with one line
naming the file, the column and the row. Row numbers are those a user sees in a spreadsheet or a text editor:
the header is row 1, the first data row is row 2. Isolated missing values (at most ``MAX_NAN_RUN`` in a row)
are interpolated linearly in time (at either end of the table: the nearest value) and noted; longer gaps are
errors, except in a displacement channel: a drift measured now and then (NaN between measurements, any spacing)
stays sparse. Several tables, sheets (``sheet: all``) or blocks of a ``run:`` column are independent runs. Columns the manifest does not name are ignored with a note in :attr:`Recording.notes`.
"""

from __future__ import annotations

import csv
import difflib
import math
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np
import pandas as pd
import yaml

from thermodrift.core.recording import file_checks
from thermodrift.core.errors import InputError
from thermodrift.core.recording import runs
from thermodrift.core.recording.types import ROLES, TEMPERATURE_ROLES, TIME_INDEX, Channel, Recording

# Per role: canonical unit and accepted units as (scale, offset) with canonical = value * scale + offset.
_TEMPERATURE = ("degC", {"degC": (1.0, 0.0), "°C": (1.0, 0.0), "K": (1.0, -273.15)})
# role -> (canonical unit, {accepted unit: (scale, offset)}); canonical = value * scale + offset
UNITS: dict[str, tuple[str, dict[str, tuple[float, float]]]] = {
    **{role: _TEMPERATURE for role in TEMPERATURE_ROLES},
    "displacement": ("um", {"um": (1.0, 0.0), "µm": (1.0, 0.0), "μm": (1.0, 0.0), "mm": (1000.0, 0.0)}),
    "speed": ("rpm", {"rpm": (1.0, 0.0), "rad_s": (60.0 / (2.0 * math.pi), 0.0),
                      "rad/s": (60.0 / (2.0 * math.pi), 0.0)}),
    "cutting_power": ("W", {"W": (1.0, 0.0), "kW": (1000.0, 0.0)}),
    "solar_irradiance": ("W_m2", {"W_m2": (1.0, 0.0), "W/m2": (1.0, 0.0), "W/m²": (1.0, 0.0),
                                  "kW_m2": (1000.0, 0.0), "kW/m2": (1000.0, 0.0), "kW/m²": (1000.0, 0.0)}),
    # A heating signal is a power, or a unitless command ("1": a boiler's modulation, a valve opening) that a model
    # takes as proportional to the heat input; it keeps unit "1" (see UNITLESS).
    "heating": ("W", {"W": (1.0, 0.0), "kW": (1000.0, 0.0), "1": (1.0, 0.0)}),
    "axis_velocity": ("mm_min", {"mm_min": (1.0, 0.0), "mm/min": (1.0, 0.0),
                                 "m_min": (1000.0, 0.0), "m/min": (1000.0, 0.0)}),
}
UNITLESS = "1"  # a signal without a physical unit: loaded as it is, canonical unit "1"
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "min": 60.0, "h": 3600.0}
_MANIFEST_KEYS = ("time", "time_unit", "sheet", "run", "channels", "description")
_TABLE_SUFFIXES = (".csv", ".parquet", ".xlsx")
# Roles whose zero variance means a dead sensor or nothing to learn (a constant speed is one condition).
_NONCONSTANT_ROLES = ("temperature", "displacement")
_SINGLE_ROLES = ("speed", "condition")

TARGET = "target"  # in ``require``: a displacement, or a temperature and another input to predict it from
MIN_ROWS = 10
MAX_NAN_RUN = 3  # longest run of missing samples that is interpolated; longer gaps are errors


@dataclass
class Manifest:
    """A validated manifest: the time column and its unit (None: timestamps), the sheet, and the channels."""

    path: str
    time: str
    time_unit: str | None
    sheet: str | list[str] | None  # a sheet, a list of sheets or "all" (each one run)
    channels: dict[str, tuple[str, str | None, dict[str, Any]]]  # column -> (role, unit, meta)
    run: str | None = None  # the column whose label blocks are independent runs


def load_recording(table_path: str | os.PathLike | Sequence[str | os.PathLike], manifest_path: str | os.PathLike,
                   *, require: Iterable[str] = ("temperature", TARGET)) -> Recording:
    """Read a table (or several) and its manifest into a :class:`Recording`; raise :class:`InputError` on bad input.

    ``table_path``: one table, a list of tables or a glob pattern (sorted); each table, each sheet of
    ``sheet: all`` (or a list of sheets) and each block of the manifest's ``run:`` column is an independent run
    (see :mod:`~thermodrift.core.recording.runs`). ``require`` lists roles that must have at least one channel,
    and :data:`TARGET`: something to model (a displacement channel, or else a temperature with at least one other
    input channel to predict it from). Default: a temperature and a target.
    """
    manifest = read_manifest(manifest_path, tuple(require))
    paths = runs.table_paths(table_path)
    tables = [(path, sheet) for path in paths for sheet in _sheets(path, manifest.sheet)]
    pieces = [piece for path, sheet in tables
              for piece in _load_table(path, sheet, manifest, runs.table_name(path, sheet, tables))]
    if len(pieces) == 1 and manifest.run is None:
        piece = pieces[0]
        frame = pd.DataFrame(piece.data, index=pd.Index(piece.time_s, name=TIME_INDEX))
        return Recording(frame, piece.channels, source=piece.source, notes=piece.notes)
    return runs.assemble(pieces)


def _sheets(path: Path, sheet: str | list[str] | None) -> list[str | None]:
    """The sheets of ``path`` to read: the manifest's one, each of a list, or every sheet for ``all``."""
    if not isinstance(sheet, list) and sheet != runs.ALL_SHEETS:
        return [sheet]
    if path.suffix.lower() != ".xlsx" or not path.is_file():
        return [None]
    if sheet == runs.ALL_SHEETS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                with pd.ExcelFile(path, engine="openpyxl") as book:
                    return [str(s) for s in book.sheet_names]
            except Exception as exc:  # zipfile, openpyxl and pandas raise different types for a broken file
                raise InputError(f"not a readable XLSX workbook ({type(exc).__name__})", file=str(path),
                                 hint="open and save it as .xlsx, or export CSV") from None
    return [str(s) for s in sheet]


def _load_table(path: Path, sheet: str | None, manifest: Manifest, name: str) -> list[runs.Piece]:
    """The runs of one table (one sheet): one, or one per block of the manifest's ``run`` column."""
    table = str(path) if sheet is None or not isinstance(manifest.sheet, list) and manifest.sheet != \
        runs.ALL_SHEETS else f"{path} (sheet {sheet!r})"
    header, body, sheet_note = _read_table(path, sheet)
    notes = [sheet_note] if sheet_note else []

    header = [h.strip() for h in header]
    positions: dict[str, list[int]] = {}
    for i, col in enumerate(header):
        positions.setdefault(col, []).append(i)
    for column in (manifest.time, *([manifest.run] if manifest.run else []), *manifest.channels):
        _locate(column, positions, header, table, manifest.path)
    if len(body) < MIN_ROWS:
        raise InputError(f"only {len(body)} data rows; at least {MIN_ROWS} are needed", file=table,
                         hint="record longer or check that the whole table was exported")
    blocks = [(name, 0, len(body))] if manifest.run is None else \
        runs.blocks(_parse_labels(body[positions[manifest.run][0]], table, manifest.run), table, manifest.run,
                    name, MIN_ROWS)

    raw_time = body[positions[manifest.time][0]]
    times = []
    for _, a, b in blocks:
        times.append(_parse_time(raw_time.iloc[a:b], manifest.time_unit, table, manifest.time, row0=a + 2))
        _note_time_gaps(times[-1], notes)

    data: dict[str, Any] = {}
    channels: dict[str, Channel] = {}
    for i, col in enumerate(header):
        spec = manifest.channels.get(col)
        if spec is None or spec[0] == "ignore" or col == manifest.run:
            continue
        role, unit, meta = spec
        raw = body[i]
        if role == "condition":
            data[col] = _parse_labels(raw, table, col)
            channels[col] = Channel(col, role, None, meta)
            continue
        values = _parse_numbers(raw, table, col)
        parts, filled = [], []
        for (run, a, b), t in zip(blocks, times):
            part, rows = _fill_gaps(values[a:b], t, table, col, row0=a + 2, sparse=role == "displacement",
                                    run=run if manifest.run else None)
            parts.append(part)
            filled += [a + r for r in rows]
        values = np.concatenate(parts)
        if filled:
            rows = ", ".join(str(r + 2) for r in filled[:5]) + (", ..." if len(filled) > 5 else "")
            notes.append(f"{col}: {len(filled)} missing value(s) interpolated linearly (rows {rows})")
        if role == "displacement" and np.isnan(values).any():
            notes.append(f"{col}: measured in {int(np.isfinite(values).sum())} of {len(values)} rows (sparse: "
                         "models fit and are scored on the measured rows)")
        if role in _NONCONSTANT_ROLES and np.nanmax(values) == np.nanmin(values):
            raise InputError(f"{role} is constant ({values[np.isfinite(values)][0]:g} {unit} in every row)",
                             file=table, column=col,
                             hint="check the sensor or mark the column role: ignore in the manifest")
        if role == "displacement":
            _check_displacement_scale(values, unit, table, col, notes)
        canonical, (scale, offset) = UNITS[role][0] if unit != UNITLESS else UNITLESS, UNITS[role][1][unit]
        if (scale, offset) != (1.0, 0.0):
            values = values * scale + offset
            notes.append(f"{col}: converted from {unit} to {canonical}")
        data[col] = values
        channels[col] = Channel(col, role, canonical, meta)

    unnamed = [h or f"<unnamed column {i + 1}>" for i, h in enumerate(header)
               if h != manifest.time and h != manifest.run and h not in manifest.channels]
    if unnamed:
        shown = ", ".join(unnamed[:10]) + (f" and {len(unnamed) - 10} more" if len(unnamed) > 10 else "")
        notes.append(f"ignored {len(unnamed)} column(s) not named in the manifest: {shown}")
    return [runs.Piece(run, table, t, {c: v[a:b] for c, v in data.items()}, channels, notes)
            for (run, a, b), t in zip(blocks, times)]


class PlausibilityWarning(UserWarning):
    """A value range that is possible but suggests a wrong unit; the recording still loads."""


# Thermal drift of a machine tool spans roughly 1 to 500 µm over a recording.
_MM_LIKE_UM = 0.5      # µm: a smaller whole range labelled um looks like mm
_UM_LIKE_MM = 5.0      # mm: a larger whole range labelled mm looks like µm


def _check_displacement_scale(values: np.ndarray, unit: str, file: str, column: str, notes: list[str]) -> None:
    """Warn (and note) when a displacement range looks like the other unit; valid files still load."""
    span = float(np.nanmax(values) - np.nanmin(values))
    if unit != "mm" and span < _MM_LIKE_UM:
        text = (f"{file}: column {column!r}: displacement spans only {span:g} {unit}; thermal drift is usually "
                f"1 to 500 µm: is it in mm? (then write unit: mm)")
    elif unit == "mm" and span > _UM_LIKE_MM:
        text = (f"{file}: column {column!r}: displacement spans {span:g} mm; thermal drift is usually "
                f"below 0.5 mm: is it in µm? (then write unit: um)")
    else:
        return
    notes.append(f"warning: {text}")
    warnings.warn(text, PlausibilityWarning, stacklevel=3)


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader that refuses duplicate mapping keys (two channels for one column would silently merge)."""


class _DuplicateKey(Exception):
    def __init__(self, key: Any, line: int, first_line: int):
        super().__init__(key, line, first_line)
        self.key, self.line, self.first_line = key, line, first_line


def _construct_unique_mapping(loader: _StrictLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen: dict[Any, int] = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in seen:
            raise _DuplicateKey(key, key_node.start_mark.line + 1, seen[key])
        seen[key] = key_node.start_mark.line + 1
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_unique_mapping)


def read_manifest(path: str | os.PathLike, require: tuple[str, ...]) -> Manifest:
    file = str(path)
    if not Path(path).exists():
        raise InputError("manifest file not found", file=file,
                         hint="check the path of the YAML manifest that gives every column a role")
    file_checks.check_manifest_file(Path(path))
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the manifest ({type(exc).__name__})", file=file,
                         hint="the manifest must be a UTF-8 YAML file") from None
    try:
        doc = yaml.load(text, Loader=_StrictLoader)
    except _DuplicateKey as dup:
        raise InputError(f"line {dup.line}: key {dup.key!r} appears twice (first on line {dup.first_line})",
                         file=file, column=str(dup.key), hint="give each column one entry") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}: " if mark is not None else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise InputError(f"{where}broken YAML ({problem})", file=file,
                         hint="check indentation, colons and quotes") from None
    if not isinstance(doc, dict):
        kind = "empty" if doc is None else f"a {type(doc).__name__}, not a mapping"
        raise InputError(f"the manifest is {kind}", file=file,
                         hint="write 'time: <column>' and 'channels: {<column>: {role: ..., unit: ...}}'")
    unknown = [str(k) for k in doc if k not in _MANIFEST_KEYS]
    if unknown:
        raise InputError(f"unknown manifest key {unknown[0]!r}", file=file,
                         hint=_suggest(unknown[0], _MANIFEST_KEYS, f"known keys: {', '.join(_MANIFEST_KEYS)}"))
    if doc.get("time") is None:
        raise InputError("the manifest has no 'time:' key", file=file,
                         hint="add 'time: <name of the time column>'")
    time_unit = doc.get("time_unit")
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise InputError(f"unknown time_unit {time_unit!r}", file=file,
                         hint=f"use one of {', '.join(TIME_UNITS)} (or leave it out for timestamps)")
    sheet = doc.get("sheet")
    channels_doc = doc.get("channels")
    if channels_doc is None:
        raise InputError("the manifest has no 'channels:' key", file=file,
                         hint="add 'channels: {<column>: {role: temperature, unit: degC}, ...}'")
    if not isinstance(channels_doc, dict) or not channels_doc:
        raise InputError("'channels' must be a non-empty mapping of column names to {role, unit}", file=file,
                         hint="e.g. 'channels: {T1: {role: temperature, unit: degC}}'")
    time_col = str(doc["time"]).strip()
    channels: dict[str, tuple[str, str | None, dict[str, Any]]] = {}
    for key, spec in channels_doc.items():
        column = str(key).strip()
        if column in channels:
            raise InputError(f"two channel keys name column {column!r} once surrounding spaces are removed",
                             file=file, column=column, hint="give each column one entry, spelled as in the header")
        if column == time_col:
            raise InputError("the time column is also listed as a channel", file=file, column=column,
                             hint="remove it from 'channels'")
        channels[column] = _channel_spec(spec, file, column)
    for role in _SINGLE_ROLES:
        cols = [c for c, (r, _, _) in channels.items() if r == role]
        if len(cols) > 1:
            raise InputError(f"{len(cols)} channels have role {role} ({', '.join(cols)}); one is allowed",
                             file=file, column=cols[1], hint="mark the others role: ignore")
    for role in require:
        if role == TARGET:
            _check_target(channels, file)
        elif not any(r == role for r, _, _ in channels.values()):
            raise InputError(f"no channel has role {role}", file=file,
                             hint=f"give at least one column 'role: {role}' with its unit")
    run = None if doc.get("run") is None else str(doc["run"]).strip()
    if run is not None and (run == time_col or channels.get(run, ("condition",))[0] != "condition"):
        raise InputError(f"the run column {run!r} is also the time column or a numeric channel", file=file,
                         column=run, hint="name a column of run labels (it may be the condition column)")
    sheets = sheet if sheet is None or sheet == runs.ALL_SHEETS else \
        [str(x) for x in sheet] if isinstance(sheet, list) else str(sheet)
    return Manifest(file, time_col, time_unit, sheets, channels, run)


def _check_target(channels: dict[str, tuple[str, str | None, dict[str, Any]]], file: str) -> None:
    """Something to model: a displacement, or a temperature and at least one other input channel."""
    roles = [r for r, _, _ in channels.values() if r not in ("condition", "ignore")]
    if "displacement" in roles or ("temperature" in roles and len(roles) >= 2):
        return
    raise InputError("no channel has role displacement, and no temperature with another input to predict it from",
                     file=file, hint="give a column 'role: displacement', or a temperature target and its inputs "
                                     "(ambient, solar_irradiance, heating, speed, other temperatures)")


def _channel_spec(spec: Any, file: str, column: str) -> tuple[str, str | None, dict[str, Any]]:
    if not isinstance(spec, dict):
        raise InputError(f"channel entry must be a mapping, got {spec!r}", file=file, column=column,
                         hint="write e.g. '{role: temperature, unit: degC}'")
    role = spec.get("role")
    if role is None:
        raise InputError("channel has no role", file=file, column=column,
                         hint=f"add role: one of {', '.join(ROLES)}")
    if role not in ROLES:
        raise InputError(f"unknown role {role!r}", file=file, column=column,
                         hint=_suggest(str(role), ROLES, f"use one of {', '.join(ROLES)}"))
    unit = spec.get("unit")
    unit = None if unit is None else str(unit)  # `unit: 1` unquoted in YAML is the number 1
    meta = {str(k): v for k, v in spec.items() if k not in ("role", "unit")}
    if role in ("condition", "ignore"):
        if role == "condition" and unit is not None:
            raise InputError(f"a condition label has no unit (got {unit!r})", file=file, column=column,
                             hint="remove the unit")
        return role, None, meta
    accepted = UNITS[role][1]
    if unit is None:
        raise InputError(f"{role} channel has no unit", file=file, column=column,
                         hint=f"add unit: one of {', '.join(accepted)}")
    if unit not in accepted:
        known_elsewhere = any(unit in units for _, units in UNITS.values())
        what = f"unit {unit!r} is not valid for role {role}" if known_elsewhere else f"unknown unit {unit!r}"
        raise InputError(what, file=file, column=column, hint=f"use one of {', '.join(accepted)}")
    return role, str(unit), meta


def _suggest(word: str, choices: Iterable[str], fallback: str) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1)
    return f"did you mean {close[0]!r}? {fallback}" if close else fallback


def _locate(column: str, positions: dict[str, list[int]], header: list[str], table: str, manifest: str) -> None:
    found = positions.get(column)
    if not found:
        listed = ", ".join(repr(h) for h in header[:12]) + (", ..." if len(header) > 12 else "")
        raise InputError(f"the table has no such column (named in manifest {manifest})", file=table,
                         column=column, hint=_suggest(column, header, f"columns are: {listed}"))
    if len(found) > 1:
        where = " and ".join(str(p + 1) for p in found)
        raise InputError(f"the header names {len(found)} columns alike (positions {where})", file=table,
                         column=column, hint="rename the duplicates so each column is unique")


def _read_table(path: Path, sheet: str | None) -> tuple[list[str], pd.DataFrame, str | None]:
    """Header names and the data rows (columns numbered 0..n-1) of a CSV, Parquet or XLSX table."""
    file = str(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        file_checks.check_path(path, "table")
    if suffix not in _TABLE_SUFFIXES:
        raise InputError(f"unsupported table type {suffix or '(no suffix)'!r}", file=file,
                         hint="save the table as .csv, .parquet or .xlsx")
    file_checks.check_table_file(path)  # bounded time and memory before pandas reads anything
    note = None
    if suffix == ".csv":
        header, body = _read_csv(path)
    elif suffix == ".parquet":
        header, body = _read_parquet(path)
    else:
        header, body = _read_xlsx(path, sheet)
    if sheet is not None and suffix != ".xlsx":
        note = f"manifest key 'sheet: {sheet}' ignored: {path.name} is not an XLSX workbook"
    if not len(body):
        raise InputError("the table has a header but no data rows", file=file,
                         hint="export the table again with its data")
    return header, body, note


def _read_csv(path: Path) -> tuple[list[str], pd.DataFrame]:
    file = str(path)
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            first = fh.readline()
        if not first.strip():
            raise InputError("empty file (the first line holds no header)", file=file,
                             hint="the first line must name the columns")
        # European exports use ';' (decimal comma) or tabs; the header line tells which.
        sep = max((",", ";", "\t"), key=first.count)
        header = next(csv.reader([first], delimiter=sep))
        body = pd.read_csv(path, sep=sep, header=0, names=list(range(len(header))), encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise InputError("the file is not UTF-8 text", file=file, hint="save the table as UTF-8 CSV") from None
    except pd.errors.EmptyDataError:
        raise InputError("empty file", file=file, hint="export the table again with a header") from None
    except pd.errors.ParserError as exc:
        found = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(exc))
        if found:
            expected, line, saw = (int(g) for g in found.groups())
            raise InputError(f"the row has {saw} fields but the header has {expected}", file=file, row=line,
                             hint="every row needs one value per header column") from None
        raise InputError(f"malformed CSV ({' '.join(str(exc).split())})", file=file) from None
    return [str(h) for h in header], body


def _read_parquet(path: Path) -> tuple[list[str], pd.DataFrame]:
    try:
        frame = pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises several types for files that are not Parquet
        raise InputError(f"not a readable Parquet file ({type(exc).__name__})", file=str(path),
                         hint="write it with pandas.DataFrame.to_parquet or save it as CSV") from None
    if not isinstance(frame.index, pd.RangeIndex):
        frame = frame.reset_index()
    header = [str(c) for c in frame.columns]
    return header, frame.set_axis(range(len(header)), axis=1)


def _read_xlsx(path: Path, sheet: str | None) -> tuple[list[str], pd.DataFrame]:
    file = str(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # openpyxl warns about styles it does not read
        try:
            book = pd.ExcelFile(path, engine="openpyxl")
        except Exception as exc:  # zipfile, openpyxl and pandas raise different types for a broken file
            raise InputError(f"not a readable XLSX workbook ({type(exc).__name__})", file=file,
                             hint="open and save it as .xlsx, or export CSV") from None
        with book:
            names = [str(s) for s in book.sheet_names]
            name = names[0] if sheet is None else sheet
            if name not in names:
                raise InputError(f"the workbook has no sheet {sheet!r}", file=file,
                                 hint=_suggest(name, names, f"sheets: {', '.join(map(repr, names))}; "
                                               "set 'sheet:' in the manifest"))
            raw = book.parse(name, header=None)
    if raw.empty:
        raise InputError(f"empty file (sheet {name!r} holds no cells)", file=file,
                         hint="put the header in row 1 and the data below it, or choose the sheet with 'sheet:'")
    if len(raw) < 2:
        raise InputError(f"sheet {name!r} has a header but no data rows", file=file,
                         hint="choose the sheet with 'sheet:' in the manifest")
    header = ["" if pd.isna(v) else _cell_text(v) for v in raw.iloc[0]]
    body = raw.iloc[1:].reset_index(drop=True).set_axis(range(raw.shape[1]), axis=1)
    return header, body


def _cell_text(value: Any) -> str:
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


def _cell_repr(value: Any) -> str:
    """A cell as a user would recognise it: strings quoted, other values as printed."""
    return repr(value) if isinstance(value, str) else str(value)


def _blank_to_nan(raw: pd.Series) -> pd.Series:
    """Cells holding only spaces count as missing, like empty cells."""
    if pd.api.types.is_numeric_dtype(raw):
        return raw
    text = raw.astype(object)
    blank = text.map(lambda v: isinstance(v, str) and not v.strip())
    return text.mask(blank)


def _parse_numbers(raw: pd.Series, file: str, column: str, row0: int = 2) -> np.ndarray:
    """Float values; NaN where the cell is empty; InputError at the first cell that is not a finite number."""
    raw = _blank_to_nan(raw)
    if pd.api.types.is_bool_dtype(raw):
        raise InputError("holds true/false values, not numbers", file=file, column=column, row=row0)
    numbers = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float, na_value=np.nan)
    bad = np.flatnonzero(raw.notna().to_numpy() & ~np.isfinite(numbers))
    if len(bad):
        value, row = raw.iloc[bad[0]], int(bad[0]) + row0
        if np.isinf(numbers[bad[0]]):
            raise InputError(f"infinite value {_cell_repr(value)}", file=file, column=column, row=row,
                             hint="leave the cell empty if the sample is missing")
        hint = ("decimal comma? write 21.5, not 21,5" if isinstance(value, str)
                and re.fullmatch(r"\s*[-+]?\d+,\d+\s*", value) else "every cell must be a number or empty")
        raise InputError(f"non-numeric value {_cell_repr(value)}", file=file, column=column, row=row, hint=hint)
    return numbers


def _parse_labels(raw: pd.Series, file: str, column: str) -> np.ndarray:
    raw = _blank_to_nan(raw)
    missing = np.flatnonzero(raw.isna().to_numpy())
    if len(missing):
        raise InputError("missing condition label", file=file, column=column, row=int(missing[0]) + 2,
                         hint="every row needs a label")
    return np.array([_cell_text(v) for v in raw], dtype=object)


def _parse_time(raw: pd.Series, unit: str | None, file: str, column: str, row0: int = 2) -> np.ndarray:
    """Times in s: numbers times the unit, or timestamps as seconds since the first row."""
    raw = _blank_to_nan(raw)
    missing = np.flatnonzero(raw.isna().to_numpy())
    if len(missing):
        raise InputError("missing time value", file=file, column=column, row=int(missing[0]) + row0,
                         hint="every row needs a time")
    if unit is not None and not _is_number(raw.iloc[0]):
        raise InputError(f"'time_unit: {unit}' given but the time column holds {_cell_repr(raw.iloc[0])}",
                         file=file, column=column, row=row0, hint="remove time_unit to read timestamps")
    if unit is not None or _is_number(raw.iloc[0]):
        seconds = _parse_numbers(raw, file, column, row0) * TIME_UNITS[unit or "s"]
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # pandas warns when it falls back to per-element parsing
            stamps = pd.to_datetime(raw, errors="coerce", utc=True)
        bad = np.flatnonzero(stamps.isna().to_numpy())
        if len(bad):
            raise InputError(f"unparsable timestamp {_cell_repr(raw.iloc[bad[0]])}", file=file, column=column,
                             row=int(bad[0]) + row0,
                             hint="use one format like 2024-05-01 12:00:15, or seconds with 'time_unit: s'")
        seconds = (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(dtype=float)
    step = np.diff(seconds)
    wrong = np.flatnonzero(step <= 0)
    if len(wrong):
        i = int(wrong[0]) + 1
        if step[i - 1] == 0:
            raise InputError(f"duplicate time {seconds[i]:g} s (same as row {i + row0 - 1})", file=file, column=column,
                             row=i + row0, hint="remove the repeated row")
        raise InputError(f"time goes backwards ({seconds[i]:g} s after {seconds[i - 1]:g} s)", file=file,
                         column=column, row=i + row0, hint="sort the table by time or fix the time column")
    return seconds


def _is_number(value: Any) -> bool:
    if isinstance(value, (bool, np.bool_)):
        return False
    try:
        float(value)
    except (TypeError, ValueError):
        return False
    return True


def _fill_gaps(values: np.ndarray, time_s: np.ndarray, file: str, column: str, row0: int = 2,
               sparse: bool = False, run: str | None = None) -> tuple[np.ndarray, list[int]]:
    """Interpolate runs of at most MAX_NAN_RUN missing samples linearly in time; longer runs are errors, except
    in a ``sparse`` channel (a drift measured now and then), which keeps every gap as NaN once one is longer.
    Row numbers in messages count from ``row0`` (the spreadsheet row of ``values[0]``)."""
    missing = np.isnan(values)
    if not missing.any():
        return values, []
    where = f" in run {run!r}" if run is not None else ""
    if missing.all():
        raise InputError(f"never measured{where} (every cell empty)", file=file, column=column, row=row0,
                         hint="measure it at least once per run, or leave the run out")
    edges = np.diff(np.r_[0, missing.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    long = np.flatnonzero(ends - starts > MAX_NAN_RUN)
    if len(long) and sparse:
        return values, []
    if len(long):
        a, b = int(starts[long[0]]), int(ends[long[0]])
        raise InputError(f"{b - a} missing values in a row{where} (rows {a + row0} to {b + row0 - 1}); at most "
                         f"{MAX_NAN_RUN} consecutive missing samples are interpolated", file=file, column=column,
                         row=a + row0, hint="fill or cut the gap, or split the recording there")
    filled = values.copy()
    filled[missing] = np.interp(time_s[missing], time_s[~missing], values[~missing])
    return filled, np.flatnonzero(missing).tolist()


def _note_time_gaps(time_s: np.ndarray, notes: list[str]) -> None:
    step = np.diff(time_s)
    median = float(np.median(step))
    gaps = np.flatnonzero(step > 10 * median)
    if len(gaps):
        i = int(gaps[0])
        notes.append(f"{len(gaps)} time gap(s) longer than 10 sampling intervals; the first: {step[i]:g} s "
                     f"before row {i + 3}")
    elif np.any(np.abs(step - median) > 0.01 * median):
        notes.append(f"irregular sampling: intervals from {step.min():g} s to {step.max():g} s "
                     f"(median {median:g} s)")
