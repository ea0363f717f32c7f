"""Errors that the CLI reports as one line with exit code 2 (bad input, never a traceback)."""

from __future__ import annotations

from thermodrift.compensator.errors import InputError  # its home is the lowest layer

__all__ = ["DuplicateComponentError", "InputError", "PluginError"]


class PluginError(Exception):
    """A plugin could not be loaded or registered a conflicting component."""


class DuplicateComponentError(PluginError):
    """Two plugins registered the same component name; the message names both origins."""
