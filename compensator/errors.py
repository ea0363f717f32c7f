"""The one error the compensator raises for what it refuses (and the CLI reports as one line, exit code 2).

It lives here, in the lowest layer, so the compensator can refuse input without importing ``thermodrift.core``;
``thermodrift.core.errors`` re-exports it for the rest of the package.
"""

from __future__ import annotations


class InputError(Exception):
    """Bad user input. ``str(err)`` is one line naming the file, column and row where known, and what to do."""

    def __init__(self, message: str, *, file: str | None = None, column: str | None = None,
                 row: int | None = None, hint: str | None = None):
        self.file, self.column, self.row, self.hint = file, column, row, hint
        where = ", ".join(p for p in (
            f"file {file}" if file else "",
            f"column {column!r}" if column is not None else "",
            f"row {row}" if row is not None else "",
        ) if p)
        text = f"{where}: {message}" if where else message
        if hint:
            text += f" ({hint})"
        super().__init__(" ".join(text.split()))


class PackageError(InputError, ValueError):
    """A folder that is not a usable compensator package; the message names the file, the entry and what to do."""

    def __init__(self, message: str, **where):
        super().__init__(f"not a usable compensator package: {message}", **where)
