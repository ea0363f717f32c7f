"""The recording loader's file checks: a table or manifest file looked at before a parser sees it, so bad input costs
bounded time and memory.

pandas and openpyxl read a whole line (or file) into memory before they can complain: a 115 MB CSV on one
line or 2 GB of NUL bytes would take gigabytes. :func:`check_table_file` looks at the file in fixed-size blocks
first: it refuses directories, oversized files, binary content (NUL bytes, compressed or UTF-16 data) in a
text table, a wrong magic number in a binary format, over-long lines, and CSV rows whose field count differs
from the header's (a short row would otherwise be read as missing values and interpolated).

Limits can be raised through the environment for unusual recordings: ``THERMODRIFT_MAX_TABLE_MB`` (default
1024) and ``THERMODRIFT_MAX_LINE_KB`` (default 1024).
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

from thermodrift.core.errors import InputError

BLOCK = 1 << 20  # bytes read at a time
MAX_MANIFEST_BYTES = 1 << 20

# Leading bytes of formats that users save under a .csv name by mistake.
_SIGNATURES = {b"\x1f\x8b": "gzip-compressed data", b"PK\x03\x04": "a ZIP archive (an XLSX workbook?)",
               b"PAR1": "a Parquet file", b"\xff\xfe": "UTF-16 text", b"\xfe\xff": "UTF-16 text",
               b"\x89PNG": "a PNG image", b"%PDF": "a PDF document", b"\xd0\xcf\x11\xe0": "an old Excel (.xls) file",
               b"BZh": "bzip2-compressed data", b"\xfd7zXZ": "xz-compressed data"}
_MAGIC = {".parquet": (b"PAR1", "Parquet file"), ".xlsx": (b"PK\x03\x04", "XLSX workbook")}


def max_table_bytes() -> int:
    return int(float(os.environ.get("THERMODRIFT_MAX_TABLE_MB", 1024)) * (1 << 20))


def max_line_bytes() -> int:
    return int(float(os.environ.get("THERMODRIFT_MAX_LINE_KB", 1024)) * (1 << 10))


def check_path(path: Path, what: str) -> None:
    """A readable regular file, else InputError naming a directory or a missing path as such."""
    if path.is_dir():
        raise InputError(f"{what} is a directory, not a file", file=str(path),
                         hint=f"pass the {what} file inside it")
    if not path.exists():
        raise InputError(f"{what} file not found", file=str(path), hint="check the path")
    if not path.is_file():
        raise InputError(f"{what} is not a regular file", file=str(path), hint=f"pass the {what} file itself")


def check_manifest_file(path: Path) -> None:
    check_path(path, "manifest")
    if path.stat().st_size > MAX_MANIFEST_BYTES:
        raise InputError(f"the manifest is {path.stat().st_size / (1 << 20):.1f} MB; a manifest is a short YAML "
                         f"file (at most {MAX_MANIFEST_BYTES >> 20} MB)", file=str(path),
                         hint="pass the YAML manifest, not the table")
    with open(path, "rb") as fh:
        head = fh.read(BLOCK)
    if b"\0" in head:
        raise InputError("the manifest holds binary data (NUL bytes)", file=str(path),
                         hint="pass the UTF-8 YAML manifest")


def check_table_file(path: Path) -> None:
    """Refuse a table that no parser should be given; CSVs are scanned block by block (bounded memory)."""
    file = str(path)
    check_path(path, "table")
    size = path.stat().st_size
    if size == 0:
        raise InputError("empty file", file=file, hint="export the table again with a header and data rows")
    suffix = path.suffix.lower()
    with open(path, "rb") as fh:
        head = fh.read(BLOCK)
    if suffix in _MAGIC:
        magic, kind = _MAGIC[suffix]
        if not head.startswith(magic):
            found = _signature(head)
            what = f"the file is {found}" if found else "wrong leading bytes"
            raise InputError(f"not a readable {kind} ({what})", file=file,
                             hint=f"save the table as {suffix} again, or as CSV")
    if suffix == ".csv":
        found = _signature(head)
        if found:
            raise InputError(f"not a CSV text table: the file is {found}", file=file,
                             hint="export the table as UTF-8 CSV")
        _check_text(head, 0, 1, path)
    if size > max_table_bytes():
        raise InputError(f"the table is {size / (1 << 20):.0f} MB, above the {max_table_bytes() >> 20} MB limit",
                         file=file, hint="split the recording, or raise THERMODRIFT_MAX_TABLE_MB")
    if suffix == ".csv":
        _scan_lines(path)
        _check_field_counts(path)


def _signature(head: bytes) -> str | None:
    return next((kind for magic, kind in _SIGNATURES.items() if head.startswith(magic)), None)


def _scan_lines(path: Path) -> None:
    """NUL bytes and lines longer than the limit, found in one pass of fixed-size blocks."""
    limit, offset, line_start, line = max_line_bytes(), 0, 0, 1
    with open(path, "rb") as fh:
        while block := fh.read(BLOCK):
            _check_text(block, offset, line, path)
            pos = block.find(b"\n")
            while pos >= 0:
                if offset + pos - line_start > limit:
                    raise _long_line(path, line, limit)
                line_start, line = offset + pos + 1, line + 1
                pos = block.find(b"\n", pos + 1)
            offset += len(block)
            if offset - line_start > limit:
                raise _long_line(path, line, limit)


def _check_text(block: bytes, offset: int, line: int, path: Path) -> None:
    nul = block.find(b"\0")
    if nul >= 0:
        at = line + block.count(b"\n", 0, nul)
        raise InputError(f"binary data: a NUL byte at byte {offset + nul} (line {at})", file=str(path),
                         hint="this is not a text table; export it as UTF-8 CSV")


def _long_line(path: Path, line: int, limit: int) -> InputError:
    return InputError(f"a line longer than {limit >> 10} KB (no line break?)", file=str(path), row=line,
                      hint="rows must end with a line break; raise THERMODRIFT_MAX_LINE_KB for very wide tables")


def _check_field_counts(path: Path) -> None:
    """Every non-blank row has as many fields as the header (same separator rule as the reader)."""
    file = str(path)
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            sep = max((",", ";", "\t"), key=fh.readline().count)
        with open(path, encoding="utf-8-sig", newline="") as fh:
            reader = csv.reader(fh, delimiter=sep)
            header = next(reader, None)
            if not header:
                return
            width, start = len(header), reader.line_num + 1
            for fields in reader:
                if fields and len(fields) != width:
                    what = "too few" if len(fields) < width else "too many"
                    hint = ("every row needs one value per header column; was the file cut off or a separator "
                            "added?")
                    if reader.line_num > start:
                        hint = f"a quote opened in this row runs on to line {reader.line_num}; close it"
                    raise InputError(f"the row has {len(fields)} fields but the header has {width} ({what})",
                                     file=file, row=start, hint=hint)
                start = reader.line_num + 1
    except UnicodeDecodeError:
        raise InputError("the file is not UTF-8 text", file=file, hint="save the table as UTF-8 CSV") from None
    except csv.Error as exc:
        raise InputError(f"malformed CSV ({exc})", file=file, hint="check quotes and separators") from None
