"""Regenerate tests/data/good and tests/data/bad (tiny committed inputs): ``python tests/data/make_corpus.py``.

Each bad case is a folder with a table, a manifest and ``expect.yaml``: which file the error must name, the
column and row (header = row 1) where the input is wrong, and a phrase of the message.
"""

from __future__ import annotations

import gzip
import shutil
from pathlib import Path

import openpyxl
import yaml

HERE = Path(__file__).parent
HEADER = ["time_s", "spindle_rpm", "ambient_C", "T1", "T2", "T3", "disp_z_um"]
MANIFEST = """\
time: time_s
channels:
  spindle_rpm: {role: speed, unit: rpm}
  ambient_C: {role: ambient, unit: degC}
  T1: {role: temperature, unit: degC, location: front_bearing}
  T2: {role: temperature, unit: degC}
  T3: {role: temperature, unit: degC}
  disp_z_um: {role: displacement, unit: um, axis: z}
"""


def rows(n: int = 20) -> list[list[object]]:
    """A small warm-up: idle for 10 samples (150 s), then 1500 rpm; temperatures rise, the spindle grows in -z."""
    out = []
    for i in range(n):
        out.append([15 * i, 0 if i < 10 else 1500, round(20.0 + 0.01 * i, 3), round(21.0 + 0.1 * i, 3),
                    round(22.0 + 0.05 * i + 0.01 * (i % 3), 3), round(20.5 + 0.02 * i, 3),
                    round(-0.5 * i + 0.03 * (i % 2), 3)])
    return out


def stamps_table() -> list[list[object]]:
    """rows() with timestamps (every 15 s from 08:00) instead of seconds."""
    out = rows()
    for i, line in enumerate(out):
        line[0] = f"2024-05-01 08:{i // 4:02d}:{15 * (i % 4):02d}"
    return out


def csv_text(table: list[list[object]], header: list[str] = HEADER, sep: str = ",") -> str:
    return "\n".join(sep.join(str(v) for v in line) for line in [header, *table]) + "\n"


def edit(table: list[list[object]], row: int, column: str, value: object) -> list[list[object]]:
    """Set a cell by the row number a user sees (header = row 1)."""
    table[row - 2][HEADER.index(column)] = value
    return table


def manifest_with(old: str, new: str) -> str:
    assert old in MANIFEST, old
    return MANIFEST.replace(old, new)


def write_xlsx(path: Path, table: list[list[object]], sheet: str) -> None:
    book = openpyxl.Workbook()
    ws = book.active
    ws.title = sheet
    for line in [HEADER, *table]:
        ws.append(line)
    book.save(path)


def case(name: str, *, expect: dict, table: str | None = None, manifest: str | None = MANIFEST,
         table_name: str = "table.csv", encoding: str = "utf-8") -> None:
    folder = HERE / "bad" / name
    folder.mkdir(parents=True)
    if table is not None:
        (folder / table_name).write_bytes(table.encode(encoding))
    if manifest is not None:
        (folder / "manifest.yaml").write_text(manifest, encoding="utf-8")
    spec = {"table": table_name, "manifest": "manifest.yaml", **expect}
    (folder / "expect.yaml").write_text(yaml.safe_dump(spec, allow_unicode=True, sort_keys=False), encoding="utf-8")


def main() -> None:
    shutil.rmtree(HERE / "bad", ignore_errors=True)
    shutil.rmtree(HERE / "good", ignore_errors=True)
    (HERE / "good").mkdir()
    (HERE / "good" / "recording.csv").write_text(csv_text(rows(40)), encoding="utf-8")
    (HERE / "good" / "recording.yaml").write_text(MANIFEST, encoding="utf-8")

    good = csv_text(rows())
    T, M = "table.csv", "manifest.yaml"
    # Table files
    case("empty_file", table="", expect={"file": T, "match": "empty file"})
    case("header_only", table=",".join(HEADER) + "\n", expect={"file": T, "match": "no data rows"})
    case("too_short", table=csv_text(rows(5)), expect={"file": T, "match": "only 5 data rows"})
    case("table_missing", expect={"file": T, "match": "table file not found"})
    case("unsupported_suffix", table=good, table_name="table.xls",
         expect={"file": "table.xls", "match": "unsupported table type"})
    case("not_utf8", table=csv_text(rows(), HEADER[:3] + ["T1 (°C)"] + HEADER[4:]), encoding="latin-1",
         manifest=MANIFEST.replace("  T1:", "  T1 (°C):"), expect={"file": T, "match": "not UTF-8"})
    case("ragged_row", table=good.replace("\n75,", "\n75,1,", 1),
         expect={"file": T, "row": 7, "match": "fields but the header has 7"})
    case("duplicate_header", table=csv_text(rows(), HEADER[:5] + ["T2"] + HEADER[6:]),
         expect={"file": T, "column": "T2", "match": "positions 5 and 6"})
    case("corrupt_xlsx", table="time_s,T1\n0,1\n", table_name="table.xlsx",
         expect={"file": "table.xlsx", "match": "not a readable XLSX"})
    short = good.splitlines()
    short[8] = short[8].rsplit(",", 2)[0]
    case("short_row", table="\n".join(short) + "\n",
         expect={"file": T, "row": 9, "match": "5 fields but the header has 7 (too few)"})
    case("cut_mid_row", table=good[:-9], expect={"file": T, "row": 21, "match": "(too few)"})
    case("short_row_semicolon", table=csv_text(rows(), sep=";").replace("\n90;", "\n90;0\n", 1),
         expect={"file": T, "row": 8, "match": "2 fields but the header has 7"})
    case("table_is_directory", table=None, table_name="table.csv",
         expect={"file": T, "match": "table is a directory"})
    (HERE / "bad" / "table_is_directory" / T).mkdir()
    (HERE / "bad" / "table_is_directory" / T / ".gitkeep").touch()  # git keeps no empty folder
    case("nul_bytes", table=good[:200] + "\0" * 64 + good[200:], expect={"file": T, "match": "NUL byte at byte 200"})
    case("gzip_named_csv", table=None, expect={"file": T, "match": "the file is gzip-compressed data"})
    (HERE / "bad" / "gzip_named_csv" / T).write_bytes(gzip.compress(good.encode(), mtime=0))
    case("xlsx_named_csv", table=None, expect={"file": T, "match": "the file is a ZIP archive"})
    write_xlsx(HERE / "bad" / "xlsx_named_csv" / T, rows(), "data")
    case("utf16_csv", table=good, encoding="utf-16", expect={"file": T, "match": "the file is UTF-16 text"})
    case("png_named_csv", table=None, expect={"file": T, "match": "the file is a PNG image"})
    (HERE / "bad" / "png_named_csv" / T).write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4)
    case("csv_named_parquet", table=good, table_name="table.parquet",
         expect={"file": "table.parquet", "match": "not a readable Parquet file (wrong leading bytes)"})
    case("truncated_parquet", table=None, table_name="table.parquet",
         expect={"file": "table.parquet", "match": "not a readable Parquet file"})
    (HERE / "bad" / "truncated_parquet" / "table.parquet").write_bytes(b"PAR1" + bytes(100))
    case("whitespace_only", table="   \n\n  \n", expect={"file": T, "match": "empty file"})
    case("duplicate_header_after_strip", table=csv_text(rows(), HEADER[:5] + [" T2 "] + HEADER[6:]),
         expect={"file": T, "column": "T2", "match": "positions 5 and 6"})
    case("true_false_cells", table=csv_text([line[:3] + [True] + line[4:] for line in rows()]),
         expect={"file": T, "column": "T1", "row": 2, "match": "holds true/false values"})
    case("negative_infinity", table=csv_text(edit(rows(), 14, "disp_z_um", "-inf")),
         expect={"file": T, "column": "disp_z_um", "row": 14, "match": "infinite value"})
    case("unclosed_quote", table=good.replace("\n90,", '\n"90,', 1),
         expect={"file": T, "row": 8, "match": "runs on to line 21"})
    # Columns and cells
    case("missing_time_column", table=csv_text(rows(), ["t"] + HEADER[1:]),
         expect={"file": T, "column": "time_s", "match": "no such column"})
    case("missing_channel_column", table=good, manifest=MANIFEST + "  T9: {role: temperature, unit: degC}\n",
         expect={"file": T, "column": "T9", "match": "no such column"})
    case("non_numeric_cell", table=csv_text(edit(rows(), 7, "T2", "abc")),
         expect={"file": T, "column": "T2", "row": 7, "match": "non-numeric value 'abc'"})
    case("infinite_value", table=csv_text(edit(rows(), 11, "T3", "inf")),
         expect={"file": T, "column": "T3", "row": 11, "match": "infinite value"})
    case("decimal_comma", table=csv_text(rows(), sep=";").replace(".", ","),
         expect={"file": T, "column": "ambient_C", "row": 2, "match": "decimal comma"})
    gap = rows()
    for r in range(8, 13):
        edit(gap, r, "T3", "")
    case("nan_gap", table=csv_text(gap), expect={"file": T, "column": "T3", "row": 8, "match": "5 missing values"})
    case("missing_time_value", table=csv_text(edit(rows(), 6, "time_s", "")),
         expect={"file": T, "column": "time_s", "row": 6, "match": "missing time value"})
    case("time_backwards", table=csv_text(edit(rows(), 9, "time_s", 60)),
         expect={"file": T, "column": "time_s", "row": 9, "match": "time goes backwards"})
    case("duplicate_time", table=csv_text(edit(rows(), 12, "time_s", 135)),
         expect={"file": T, "column": "time_s", "row": 12, "match": "duplicate time 135 s"})
    stamps = stamps_table()
    stamps[7][0] = "yesterday"
    case("unparsable_timestamp", table=csv_text(stamps),
         expect={"file": T, "column": "time_s", "row": 9, "match": "unparsable timestamp 'yesterday'"})
    flat = rows()
    for line in flat:
        line[HEADER.index("disp_z_um")] = 0.0
    case("constant_displacement", table=csv_text(flat),
         expect={"file": T, "column": "disp_z_um", "match": "displacement is constant"})
    flat = rows()
    for line in flat:
        line[HEADER.index("T1")] = 21.0
    case("constant_temperature", table=csv_text(flat),
         expect={"file": T, "column": "T1", "match": "temperature is constant"})
    labelled = [line + [("warmup" if i < 10 else "cut") if i != 13 else ""] for i, line in enumerate(rows())]
    case("missing_condition_label", table=csv_text(labelled, HEADER + ["phase"]),
         manifest=MANIFEST + "  phase: {role: condition}\n",
         expect={"file": T, "column": "phase", "row": 15, "match": "missing condition label"})
    xlsx = HERE / "bad" / "wrong_sheet"
    case("wrong_sheet", table_name="table.xlsx", manifest="sheet: Messung\n" + MANIFEST,
         expect={"file": "table.xlsx", "match": "no sheet 'Messung'"})
    write_xlsx(xlsx / "table.xlsx", rows(), "Daten")
    # Manifests
    case("manifest_missing", table=good, manifest=None, expect={"file": M, "match": "manifest file not found"})
    case("manifest_empty", table=good, manifest="", expect={"file": M, "match": "manifest is empty"})
    case("manifest_is_directory", table=good, manifest=None, expect={"file": M, "match": "manifest is a directory"})
    (HERE / "bad" / "manifest_is_directory" / M).mkdir()
    (HERE / "bad" / "manifest_is_directory" / M / ".gitkeep").touch()  # git keeps no empty folder
    case("manifest_binary", table=good, manifest=MANIFEST + "\0\0\0\n", expect={"file": M, "match": "binary data"})
    case("manifest_not_utf8", table=good, manifest=None, expect={"file": M, "match": "cannot read the manifest"})
    (HERE / "bad" / "manifest_not_utf8" / M).write_bytes(MANIFEST.replace("front_bearing", "Lager vorn ä")
                                                          .encode("latin-1"))
    case("manifest_keys_equal_after_strip", table=good, manifest=MANIFEST + '  " T1": {role: temperature, unit: K}\n',
         expect={"file": M, "column": "T1", "match": "once surrounding spaces are removed"})
    case("two_condition_channels", table=good,
         manifest=MANIFEST + "  T2b: {role: condition}\n  T3b: {role: condition}\n",
         expect={"file": M, "column": "T3b", "match": "2 channels have role condition"})
    case("condition_with_unit", table=good, manifest=MANIFEST + "  phase: {role: condition, unit: s}\n",
         expect={"file": M, "column": "phase", "match": "a condition label has no unit"})
    case("role_is_a_list", table=good, manifest=manifest_with("T2: {role: temperature", "T2: {role: [temperature]"),
         expect={"file": M, "column": "T2", "match": "unknown role"})
    case("time_unit_with_timestamps", table=csv_text(stamps_table()), manifest="time_unit: s\n" + MANIFEST,
         expect={"file": T, "column": "time_s", "row": 2, "match": "'time_unit: s' given"})
    case("displacement_unit_kelvin", table=good, manifest=manifest_with("unit: um, axis: z", "unit: K, axis: z"),
         expect={"file": M, "column": "disp_z_um", "match": "not valid for role displacement"})
    case("broken_yaml", table=good, manifest=MANIFEST.replace("  T2: {role", "  T2: {role: [", 1),
         expect={"file": M, "match": "broken YAML"})
    case("manifest_not_mapping", table=good, manifest="- time_s\n- T1\n", expect={"file": M, "match": "not a mapping"})
    case("unknown_manifest_key", table=good, manifest="time_units: s\n" + MANIFEST,
         expect={"file": M, "match": "unknown manifest key 'time_units'"})
    case("no_time_key", table=good, manifest=MANIFEST.replace("time: time_s\n", ""),
         expect={"file": M, "match": "no 'time:' key"})
    case("bad_time_unit", table=good, manifest="time_unit: days\n" + MANIFEST,
         expect={"file": M, "match": "unknown time_unit 'days'"})
    case("missing_channels", table=good, manifest="time: time_s\n", expect={"file": M, "match": "no 'channels:' key"})
    case("channels_not_mapping", table=good, manifest="time: time_s\nchannels: [T1, disp_z_um]\n",
         expect={"file": M, "match": "non-empty mapping"})
    case("channel_entry_not_mapping", table=good, manifest=manifest_with("T2: {role: temperature, unit: degC}",
                                                                          "T2: temperature"),
         expect={"file": M, "column": "T2", "match": "must be a mapping"})
    case("missing_role", table=good, manifest=manifest_with("T2: {role: temperature, unit: degC}", "T2: {unit: degC}"),
         expect={"file": M, "column": "T2", "match": "has no role"})
    case("unknown_role", table=good, manifest=manifest_with("T2: {role: temperature", "T2: {role: temprature"),
         expect={"file": M, "column": "T2", "match": "unknown role 'temprature'"})
    case("missing_unit", table=good, manifest=manifest_with("{role: displacement, unit: um, axis: z}",
                                                            "{role: displacement, axis: z}"),
         expect={"file": M, "column": "disp_z_um", "match": "has no unit"})
    case("unknown_unit", table=good, manifest=manifest_with("T1: {role: temperature, unit: degC",
                                                            "T1: {role: temperature, unit: degF"),
         expect={"file": M, "column": "T1", "match": "unknown unit 'degF'"})
    case("unit_wrong_for_role", table=good, manifest=manifest_with("T3: {role: temperature, unit: degC}",
                                                                   "T3: {role: temperature, unit: mm}"),
         expect={"file": M, "column": "T3", "match": "not valid for role temperature"})
    case("duplicate_channel_column", table=good, manifest=MANIFEST + "  T1: {role: ambient, unit: degC}\n",
         expect={"file": M, "column": "T1", "match": "appears twice"})
    case("time_also_channel", table=good, manifest=MANIFEST + "  time_s: {role: temperature, unit: degC}\n",
         expect={"file": M, "column": "time_s", "match": "also listed as a channel"})
    case("two_speed_channels", table=good, manifest=manifest_with("ambient_C: {role: ambient, unit: degC}",
                                                                  "ambient_C: {role: speed, unit: rpm}"),
         expect={"file": M, "column": "ambient_C", "match": "2 channels have role speed"})
    case("no_temperature_channel", table=good,
         manifest="time: time_s\nchannels:\n  disp_z_um: {role: displacement, unit: um}\n",
         expect={"file": M, "match": "no channel has role temperature"})
    case("no_displacement_channel", table=good,
         manifest="time: time_s\nchannels:\n  T1: {role: temperature, unit: degC}\n",
         expect={"file": M, "match": "no channel has role displacement"})


if __name__ == "__main__":
    main()


def write_large_cases(folder: Path) -> dict[str, tuple[Path, Path, str]]:
    """Inputs too large to commit, written at test time into ``folder``: name -> (table, manifest, phrase).

    The 2 GB files are sparse (all NUL bytes, no disk blocks), the 115 MB line is streamed in 1 MB pieces.
    """
    folder.mkdir(parents=True, exist_ok=True)
    manifest = folder / "manifest.yaml"
    manifest.write_text(MANIFEST, encoding="utf-8")
    cases = {}
    line = folder / "one_line_115mb.csv"
    with open(line, "wb") as fh:
        fh.write(",".join(HEADER).encode())
        piece = b",21.5" * (1 << 18)  # 1.25 MB, no line break anywhere
        for _ in range(92):
            fh.write(piece)
    cases["one_line_115mb"] = (line, manifest, "a line longer than 1024 KB")
    for name, suffix, phrase in (("binary_2gb", ".csv", "NUL byte at byte 0"),
                                 ("binary_2gb_xlsx", ".xlsx", "not a readable XLSX workbook"),
                                 ("binary_2gb_parquet", ".parquet", "not a readable Parquet file")):
        path = folder / f"{name}{suffix}"
        with open(path, "wb") as fh:
            fh.truncate(2 << 30)
        cases[name] = (path, manifest, phrase)
    big_manifest = folder / "huge_manifest.yaml"
    with open(big_manifest, "w", encoding="utf-8") as fh:
        fh.write(MANIFEST)
        for i in range(40_000):
            fh.write(f"  extra_{i}: {{role: ignore}}\n")
    cases["huge_manifest"] = (HERE / "good" / "recording.csv", big_manifest, "a manifest is a short YAML file")
    return cases
