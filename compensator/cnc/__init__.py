"""Controller formats: the values a CNC accepts, in the units and step limits its documentation fixes.

One module per format, each registered through the ``thermodrift`` entry points (:mod:`..discovery`), so a
third-party package adds a controller in one file plus one entry-point line::

    from thermodrift.compensator.cnc import Format

    class MyController(Format):
        \"\"\"One line on what the controller reads (units).\"\"\"

        def header(self):
            return ["time_s"] + [f"{t}_um" for t in self.targets]

        def rows(self, step):          # a guard.Step: written µm per target, statuses, time in s
            return [[step.time_s, *step.written]]

    def thermodrift_register_cnc_formats(registry):
        registry.add("cnc", "my_controller", MyController)

Built in: ``csv`` (:mod:`.csv_table`), ``siemens``, ``fanuc``, ``beckhoff``. :func:`writer` builds a format by
name; the settings every format receives are those of :class:`Format`.
"""

from __future__ import annotations

import difflib
from typing import Any

from thermodrift.compensator.cnc.base import Axis, Format, axes_of, axis_line, number
from thermodrift.compensator.errors import InputError

__all__ = ["Axis", "Format", "axes_of", "axis_line", "formats", "number", "writer"]


def formats() -> dict[str, type]:
    """Name -> class of every installed controller format."""
    from thermodrift.compensator import discovery

    return discovery.components("cnc")


def writer(package, fmt: str = "csv", **settings: Any) -> Format:
    """The format ``fmt`` for ``package`` with ``settings`` (see :class:`Format`); an unknown name is one
    :class:`InputError` with the closest known one."""
    from thermodrift.compensator import discovery

    factory = discovery.find("cnc", fmt)
    if factory is None:
        known = formats()
        close = difflib.get_close_matches(fmt, list(known), n=1)
        raise InputError(f"unknown CNC format {fmt!r}", hint=(f"did you mean {close[0]!r}? " if close else "")
                         + f"choose from {', '.join(sorted(known))}")
    return factory(package, **settings)
