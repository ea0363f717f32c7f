"""Dataset "buildings": three real residential buildings (15 min, winter; indoor temperature from weather and heating).

The tables are not shipped. ``house`` (1, 2 or 3) picks ``blg_<house>.csv`` in the folder given as ``path``, else
``$THERMODRIFT_BUILDINGS``, else ``../shared/data/buildings`` from the current directory. The manifest
(``buildings.yaml`` beside this module) gives ``Ta`` (outdoor °C, role ambient), ``Ps`` (solar irradiance, kW/m²,
loaded in W/m²), ``Thm`` (the boiler's heating signal, unitless) and ``yTi`` (indoor °C, role temperature): the
target, so run with ``targets=['yTi']`` (errors in K).
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

from thermodrift.core.errors import InputError
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.recording import Recording, load_recording

ENV_PATH = "THERMODRIFT_BUILDINGS"
DEFAULT_PATH = Path("..", "shared", "data", "buildings")
HOUSES = (1, 2, 3)
TARGET = "yTi"
SOURCE_URL = "https://github.com/JulienLeprince/fiftyshadesofgrey (files data/in/blg_1.csv ... blg_3.csv, MIT licence)"


def buildings(house: int = 1, path: str | None = None) -> Recording:
    """House ``house`` (1, 2 or 3) from ``path`` (the folder or the CSV), ``$THERMODRIFT_BUILDINGS`` or the default."""
    if house not in HOUSES:
        raise InputError(f"dataset buildings has houses {', '.join(map(str, HOUSES))}, not {house!r}",
                         hint="pass dataset.params.house=1, 2 or 3")
    table = _find_table(int(house), path)
    with resources.as_file(resources.files(__package__) / "buildings.yaml") as manifest:
        return load_recording(table, manifest)


def _find_table(house: int, path: str | None) -> Path:
    given = path or os.environ.get(ENV_PATH)
    candidate = Path(given).expanduser() if given else DEFAULT_PATH
    if candidate.is_dir() or not candidate.suffix:
        candidate = candidate / f"blg_{house}.csv"
    if not candidate.is_file():
        origin = ("the path given" if path else f"${ENV_PATH}" if given
                  else f"the default {DEFAULT_PATH} (relative to {Path.cwd()})")
        raise InputError(f"buildings table blg_{house}.csv not found at {origin}", file=str(candidate),
                         hint=f"download it from {SOURCE_URL} and pass path=... or set {ENV_PATH}")
    return candidate


@hookimpl
def thermodrift_register_datasets(registry):
    registry.add("dataset", "buildings", buildings)
