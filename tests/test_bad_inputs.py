"""Every malformed input in tests/data/bad gives one clear line naming file, column and row, in Python and the CLI.

Each case folder holds a table, a manifest and expect.yaml (see tests/data/make_corpus.py). Inputs too large to
commit (a 115 MB line, 2 GB of NUL bytes) are written at test time; hypothesis fuzzes tables and manifests.
Time and memory per case are measured by ``thermodrift bench bad_inputs``.
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
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from thermodrift.core import cli
from thermodrift.core.errors import InputError
from thermodrift.core.recording import PlausibilityWarning, Recording, load_recording

BAD = Path(__file__).parent / "data" / "bad"
CASES = sorted(p.name for p in BAD.iterdir() if p.is_dir())
THERMODRIFT = Path(sys.executable).with_name("thermodrift")
sys.path.insert(0, str(BAD.parent))
import make_corpus  # noqa: E402  (tests/data/make_corpus.py: the corpus and its large cases)

LARGE = ("one_line_115mb", "binary_2gb", "binary_2gb_xlsx", "binary_2gb_parquet", "huge_manifest")


def expectation(case: str) -> dict:
    spec = yaml.safe_load((BAD / case / "expect.yaml").read_text(encoding="utf-8"))
    spec["table"], spec["manifest"] = BAD / case / spec["table"], BAD / case / spec["manifest"]
    spec["file"] = str(BAD / case / spec["file"])
    return spec


def test_corpus_covers_at_least_sixty_kinds():
    assert len(CASES) + len(LARGE) >= 60


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


@pytest.fixture(scope="module")
def large_results(tmp_path_factory) -> dict[str, tuple[str, subprocess.CompletedProcess]]:
    """The installed `thermodrift validate` on the large cases, written into a temporary folder."""
    cases = make_corpus.write_large_cases(tmp_path_factory.mktemp("large"))
    assert set(cases) == set(LARGE)

    def validate(item):
        name, (table, manifest, phrase) = item
        return name, (phrase, subprocess.run([str(THERMODRIFT), "validate", str(table), "--manifest", str(manifest)],
                                             capture_output=True, text=True, timeout=120))
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
        return dict(pool.map(validate, cases.items()))


@pytest.mark.parametrize("case", LARGE)
def test_large_input_exits_2_with_one_line_and_no_traceback(case, large_results):
    phrase, result = large_results[case]
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and phrase in lines[0], result.stderr


def _write_good(folder: Path, scale: float = 1.0, unit: str = "um") -> tuple[Path, Path]:
    table = [line[:-1] + [line[-1] * scale] for line in make_corpus.rows(40)]
    (folder / "t.csv").write_text(make_corpus.csv_text(table), encoding="utf-8")
    (folder / "m.yaml").write_text(make_corpus.MANIFEST.replace("unit: um", f"unit: {unit}"), encoding="utf-8")
    return folder / "t.csv", folder / "m.yaml"


@pytest.mark.parametrize("scale, unit", [(1e-3, "um"), (1.0, "mm")])
def test_a_displacement_range_in_the_other_unit_warns_and_still_loads(tmp_path, scale, unit):
    table, manifest = _write_good(tmp_path, scale, unit)
    with pytest.warns(PlausibilityWarning, match="disp_z_um"):
        rec = load_recording(table, manifest)
    assert len(rec) == 40 and any(n.startswith("warning:") for n in rec.notes)


def test_a_plausible_displacement_loads_without_warning(tmp_path):
    table, manifest = _write_good(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(load_recording(table, manifest)) == 40


# Property-based fuzzing: whatever the bytes, loading returns a recording or raises one-line InputError.
_cell = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers().map(str),
                  st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=6),
                  st.sampled_from(["", " ", "nan", "inf", "1,5", '"', "true", "2024-05-01 08:00:00"]))
_FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _load_or_input_error(table: Path, manifest: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlausibilityWarning)
        try:
            rec = load_recording(table, manifest)
        except InputError as exc:
            assert "\n" not in str(exc) and str(exc)
            return
    assert isinstance(rec, Recording) and len(rec) >= 10


@_FUZZ
@given(body=st.lists(st.lists(_cell, min_size=0, max_size=9), min_size=0, max_size=25),
       sep=st.sampled_from([",", ";", "\t"]), raw=st.binary(max_size=64), mangle=st.integers(0, 3))
def test_fuzzed_tables_load_or_fail_with_one_line(tmp_path, body, sep, raw, mangle):
    good = make_corpus.rows(25)
    lines = [sep.join(make_corpus.HEADER)] + [sep.join(str(v) for v in row) for row in good]
    for i, row in enumerate(body):  # overwrite some rows with fuzzed cells (any field count)
        lines[1 + i % len(good)] = sep.join(row)
    text = "\n".join(lines).encode("utf-8", "surrogatepass")
    data = [text, text + raw, raw + text, text[: len(text) // 2] + raw][mangle]
    (tmp_path / "t.csv").write_bytes(data)
    (tmp_path / "m.yaml").write_text(make_corpus.MANIFEST, encoding="utf-8")
    _load_or_input_error(tmp_path / "t.csv", tmp_path / "m.yaml")


_scalar = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=8),
                    st.sampled_from(["temperature", "displacement", "speed", "degC", "um", "mm", "rpm", "K", "time_s",
                                     "T1", " T1", "disp_z_um", "condition", "ignore"]))
_yaml_value = st.recursive(_scalar, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                           st.dictionaries(_scalar, inner, max_size=4)), max_leaves=12)
_channel = st.fixed_dictionaries({"role": _scalar}, optional={"unit": _scalar, "axis": _scalar})


@_FUZZ
@given(doc=st.fixed_dictionaries({}, optional={"time": _scalar, "time_unit": _scalar, "sheet": _scalar,
                                               "channels": st.one_of(_yaml_value, st.dictionaries(
                                                   st.sampled_from(make_corpus.HEADER + [" T1", "x"]), _channel,
                                                   max_size=7)),
                                               "other": _yaml_value}),
       mangle=st.sampled_from(["", "\t", ": :", "{", "&a x\n*a"]))
def test_fuzzed_manifests_load_or_fail_with_one_line(tmp_path, doc, mangle):
    (tmp_path / "t.csv").write_text(make_corpus.csv_text(make_corpus.rows(25)), encoding="utf-8")
    text = yaml.safe_dump(doc, allow_unicode=True) + mangle
    (tmp_path / "m.yaml").write_text(text, encoding="utf-8", errors="surrogatepass")
    _load_or_input_error(tmp_path / "t.csv", tmp_path / "m.yaml")


@_FUZZ
@given(values=st.lists(st.floats(-1e6, 1e6), min_size=12, max_size=30))
def test_fuzzed_displacement_values_never_break_loading(tmp_path, values):
    table = [line[:-1] + [v] for line, v in zip(make_corpus.rows(len(values)), values)]
    (tmp_path / "t.csv").write_text(make_corpus.csv_text(table), encoding="utf-8")
    (tmp_path / "m.yaml").write_text(make_corpus.MANIFEST, encoding="utf-8")
    _load_or_input_error(tmp_path / "t.csv", tmp_path / "m.yaml")
