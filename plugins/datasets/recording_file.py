"""Dataset "recording_file": any recording given as a table (CSV, Parquet, XLSX) and its YAML manifest."""

from __future__ import annotations

import tempfile
from pathlib import Path

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.recording import Recording, load_recording


def recording_file(table: str | list[str], manifest: str) -> Recording:
    """Load ``table`` with ``manifest``; bad input raises InputError naming file, column and row. A list of tables
    (or a glob pattern) is one machine's independent runs."""
    return load_recording(table if isinstance(table, str) else [str(t) for t in table], manifest)


def _test_params() -> list[dict]:
    """The conformance suite's tiny recording written to a temporary CSV and manifest."""
    from thermodrift.testing.data import tiny_recording

    folder = Path(tempfile.mkdtemp(prefix="thermodrift-recording-file-"))
    tiny_recording(seed=0).write(folder / "tiny.csv", folder / "tiny.yaml")
    return [{"table": str(folder / "tiny.csv"), "manifest": str(folder / "tiny.yaml")}]


recording_file.get_test_params = _test_params


@hookimpl
def thermodrift_register_datasets(registry):
    registry.add("dataset", "recording_file", recording_file)
