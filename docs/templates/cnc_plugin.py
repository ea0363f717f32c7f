"""Template: a thermodrift controller format (the values one CNC or PLC accepts) in one file.

How to use:
1. Copy this file into your package, e.g. ``my_controllers/ncx.py``, and rename class and registry name.
2. Fill in the ``todo`` parts. Keep the rules: ``header()`` names the columns, the first one ``time_s``;
   ``rows(step)`` returns one or more rows per update, each as long as the header, cells text or integers (never
   empty); the same updates give the same rows. The base class (:class:`thermodrift.compensator.cnc.Format`)
   gives ``self.targets``, ``self.axes`` (targets grouped per axis, with positions), ``self.line(axis, values)``
   (offset and slope of an axis) and the settings (``reference_mm``, ``detection_unit_um``, ...). Set
   ``units = None`` only if the format can write temperature targets too.
3. One entry-point line in your ``pyproject.toml``::

       [project.entry-points.thermodrift]
       ncx = "my_controllers.ncx"

4. ``thermodrift compensate PKG --input T.csv --manifest M.yaml --out values.csv --cnc ncx`` writes it;
   ``thermodrift plugins`` lists it; a controller-side program gets it with
   ``thermodrift.compensator.cnc.writer(package, "ncx")`` (no training stack needed).
5. Check it: ``from thermodrift.testing import check_component; check_component("cnc", "ncx")``
   or subclass ``thermodrift.testing.pytest_components.CncFormatTests`` with ``name = "ncx"``.

The example writes one offset per axis in whole micrometres at the reference position, and the axis status.
"""

from thermodrift.compensator.cnc import Format
from thermodrift.compensator.guard import STATUSES
from thermodrift.core.hookspecs import hookimpl


# todo: rename the class and say what the controller reads (units)
class AxisOffsets(Format):
    """One offset per axis in whole µm at the reference position, and the most severe status of its targets."""

    def header(self):
        return ["time_s"] + [f"{a.name}_offset_um" for a in self.axes] + [f"{a.name}_status" for a in self.axes]

    # todo: step.written (µm per target), step.status (codes into STATUSES), step.time_s (s)
    def rows(self, step):
        offsets = [int(round(self.line(a, step.written)[0])) for a in self.axes]
        status = [STATUSES[max(step.status[i] for i in a.targets)] for a in self.axes]
        return [[repr(float(step.time_s))] + offsets + status]


@hookimpl
def thermodrift_register_cnc_formats(registry):
    registry.add("cnc", "axis_offsets", AxisOffsets)
