"""Every malformed input in tests/data/bad gives one clear line naming file, column and row, in Python and the CLI.

Each case folder holds a table, a manifest and expect.yaml (see tests/data/make_corpus.py).
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import yaml

from thermodrift.core import cli
from thermodrift.core.errors import InputError
from thermodrift.core.recording import load_recording

BAD = Path(__file__).parent / "data" / "bad"
CASES = sorted(p.name for p in BAD.iterdir() if p.is_dir())
THERMODRIFT = Path(sys.executable).with_name("thermodrift")


def expectation(case: str) -> dict:
    spec = yaml.safe_load((BAD / case / "expect.yaml").read_text(encoding="utf-8"))
    spec["table"], spec["manifest"] = BAD / case / spec["table"], BAD / case / spec["manifest"]
    spec["file"] = str(BAD / case / spec["file"])
    return spec


def test_corpus_covers_at_least_twenty_kinds():
    assert len(CASES) >= 20


@pytest.mark.parametrize("case", CASES)
def test_bad_input_raises_one_line_naming_file_column_row(case):
    spec = expectation(case)
    with pytest.raises(InputError) as caught:
        load_recording(spec["table"], spec["manifest"])
    err, text = caught.value, str(caught.value)
    assert "\n" not in text
    assert err.file == spec["file"] and spec["file"] in text
    assert spec["match"] in text
    assert err.column == spec.get("column")
    assert err.row == spec.get("row")
    if "column" in spec:
        assert f"column {spec['column']!r}" in text
    if "row" in spec:
        assert f"row {spec['row']}" in text


# One fresh interpreter per kind of reader (CSV, XLSX, YAML, missing files, cell and time checks): a process
# costs about a second of CPU for importing pandas, so the whole corpus goes through the CLI in-process below.
SUBPROCESS_CASES = ("empty_file", "ragged_row", "not_utf8", "corrupt_xlsx", "wrong_sheet", "broken_yaml",
                    "manifest_missing", "non_numeric_cell", "unparsable_timestamp")


def test_subprocess_cases_are_in_the_corpus():
    assert set(SUBPROCESS_CASES) <= set(CASES)


@pytest.mark.parametrize("case", CASES)
def test_cli_validate_exits_2_with_one_line(case, capsys):
    spec = expectation(case)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning would be a second line on stderr
        code = cli.main(["validate", str(spec["table"]), "--manifest", str(spec["manifest"])])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and spec["file"] in err and spec["match"] in err


@pytest.fixture(scope="module")
def subprocess_results() -> dict[str, subprocess.CompletedProcess]:
    """The installed `thermodrift validate` on SUBPROCESS_CASES, run side by side."""
    def validate(case: str) -> subprocess.CompletedProcess:
        spec = expectation(case)
        return subprocess.run([str(THERMODRIFT), "validate", str(spec["table"]), "--manifest", str(spec["manifest"])],
                              capture_output=True, text=True, timeout=120)
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
        return dict(zip(SUBPROCESS_CASES, pool.map(validate, SUBPROCESS_CASES)))


@pytest.mark.parametrize("case", SUBPROCESS_CASES)
def test_installed_cli_exits_2_with_one_line_and_no_traceback(case, subprocess_results):
    spec, result = expectation(case), subprocess_results[case]
    assert result.returncode == 2, result.stderr
    assert result.stdout == ""
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert spec["file"] in lines[0] and spec["match"] in lines[0]
