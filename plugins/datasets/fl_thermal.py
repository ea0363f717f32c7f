"""Dataset "fl_thermal": the public FL_THERMAL spindle recording (46.3 h, 15 s, 16 temperatures, 5 displacements).

The workbook is not shipped. It is looked up at ``path``, else ``$THERMODRIFT_FL_THERMAL``, else
``../shared/data/fl_thermal/data.xlsx`` from the current directory. Parsing the XLSX takes seconds, so the
parsed table is cached as Parquet in the user cache directory (``$THERMODRIFT_CACHE_DIR``, else
``$XDG_CACHE_HOME/thermodrift``, else ``~/.cache/thermodrift``), keyed by the workbook's size and mtime.
"""

from __future__ import annotations

import os
import warnings
from importlib import resources
from pathlib import Path

import pandas as pd

from thermodrift.core.errors import InputError
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.recording import Recording, load_recording

ENV_PATH = "THERMODRIFT_FL_THERMAL"
DEFAULT_PATH = Path("..", "shared", "data", "fl_thermal", "data.xlsx")
SOURCE_URL = "https://github.com/CAIVIAC/FL_THERMAL (file data/data.xlsx, MIT licence)"


def fl_thermal(path: str | None = None) -> Recording:
    """Load FL_THERMAL from ``path`` (the workbook or its folder), ``$THERMODRIFT_FL_THERMAL`` or the default."""
    workbook = _find_workbook(path)
    with resources.as_file(resources.files(__package__) / "fl_thermal.yaml") as manifest:
        cached = _cached_table(workbook)
        recording = load_recording(cached or workbook, manifest)
    recording.source = str(workbook)
    return recording


def _find_workbook(path: str | None) -> Path:
    given = path or os.environ.get(ENV_PATH)
    candidate = Path(given).expanduser() if given else DEFAULT_PATH
    if candidate.is_dir():
        candidate = candidate / "data.xlsx"
    if not candidate.is_file():
        origin = ("the path given" if path else f"${ENV_PATH}" if given
                  else f"the default {DEFAULT_PATH} (relative to {Path.cwd()})")
        raise InputError(f"FL_THERMAL workbook not found at {origin}", file=str(candidate),
                         hint=f"download it from {SOURCE_URL} and pass path=... or set {ENV_PATH}")
    return candidate


def _cache_dir() -> Path:
    explicit = os.environ.get("THERMODRIFT_CACHE_DIR")
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "thermodrift"


def _cached_table(workbook: Path) -> Path | None:
    """Parquet copy of the workbook's first sheet, written on first use; None where no cache can be written."""
    stat = workbook.stat()
    cached = _cache_dir() / f"fl_thermal-{stat.st_size}-{stat.st_mtime_ns}.parquet"
    if cached.is_file():
        return cached
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # openpyxl warns about styles it does not read
            table = pd.read_excel(workbook, sheet_name=0)
    except Exception:  # a broken workbook: load_recording reads it again and reports why, with the file name
        return None
    try:
        cached.parent.mkdir(parents=True, exist_ok=True)
        for stale in cached.parent.glob("fl_thermal-*.parquet"):
            stale.unlink(missing_ok=True)
        partial = cached.with_name(f"{cached.name}.{os.getpid()}.tmp")
        table.to_parquet(partial, index=False)
        os.replace(partial, cached)  # atomic: a concurrent reader never sees half a file
    except OSError:
        return None  # read-only home or full disk: load the workbook directly every time
    return cached


@hookimpl
def thermodrift_register_datasets(registry):
    registry.add("dataset", "fl_thermal", fl_thermal)
