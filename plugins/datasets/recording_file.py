"""Dataset "recording_file": any recording given as a table (CSV, Parquet, XLSX) and its YAML manifest."""

from __future__ import annotations

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.recording import Recording, load_recording


def recording_file(table: str, manifest: str) -> Recording:
    """Load ``table`` with ``manifest``; bad input raises InputError naming file, column and row."""
    return load_recording(table, manifest)


@hookimpl
def thermodrift_register_datasets(registry):
    registry.add("dataset", "recording_file", recording_file)
