"""Errors that the CLI reports as one line with exit code 2 (bad input, never a traceback)."""

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


class PluginError(Exception):
    """A plugin could not be loaded or registered a conflicting component."""


class DuplicateComponentError(PluginError):
    """Two plugins registered the same component name; the message names both origins."""
