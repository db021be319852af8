"""Operators' file formats: a mission's ``tasks:`` and ``obstacles:`` may be ``{file: PATH}``.

One module per format (:mod:`.qgc_plan`, :mod:`.geojson_file`, :mod:`.kml_file`, :mod:`.csv_file`),
chosen here by the file's extension; :mod:`.common` converts what they read to the mission's ENU
frame. The readers only say what the file says; the loader (:mod:`fleetctl.mission.loader`) then
validates the tasks and obstacles exactly like lists written in the mission file. Writing plans
for other tools (``fleetctl plan --export DIR``) is :mod:`.export`. docs/formats.md is the
user's reference.

To add a format: a module here with ``parse(raw bytes) -> document``, ``points(document) -> (raw
points, planned home or None)`` and ``polygons(document) -> raw polygons``, and its extension in
:data:`READERS`.
"""

from __future__ import annotations

import importlib
import logging
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleetctl.geo import Origin
from fleetctl.mission.formats.common import (
    FormatError,
    ObstacleRecord,
    RawPoint,
    RawPolygon,
    TaskRecord,
    Vec3,
    read_bounded,
    to_obstacles,
    to_tasks,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Reader:
    name: str
    parse: Callable[[bytes], Any]  # the file's bytes -> a document for points/polygons
    points: Callable[[Any], tuple[list[RawPoint], Vec3 | None]]
    polygons: Callable[[Any], list[RawPolygon]]


# extension -> (format, module of this package); a module is imported when a file of its kind is read
READERS: dict[str, tuple[str, str]] = {
    ".plan": ("QGroundControl plan", "qgc_plan"),
    ".geojson": ("GeoJSON", "geojson_file"),
    ".json": ("GeoJSON", "geojson_file"),
    ".kml": ("KML", "kml_file"),
    ".csv": ("CSV", "csv_file"),
}


def reader_for(path: Path) -> Reader:
    entry = READERS.get(path.suffix.lower())
    if entry is None:
        raise FormatError("", f"unknown file type {path.suffix or '(no extension)'!r}; use one of "
                              f"{', '.join(READERS)} (QGroundControl plan, GeoJSON, KML, CSV)")
    module = importlib.import_module(f"{__name__}.{entry[1]}")
    return Reader(entry[0], module.parse, module.points, module.polygons)


def _named(shown: str, exc: FormatError) -> FormatError:
    return FormatError(f"{shown}: {exc.where}" if exc.where else shown, exc.message)


def read_tasks(path: Path, origin: Origin | None, shown: str | None = None) -> list[TaskRecord]:
    """The tasks in ``path`` (ENU metres); ``shown`` names the file in messages (default: path)."""
    shown = shown or str(path)
    try:
        reader = reader_for(path)
        raw, home = reader.points(reader.parse(read_bounded(path)))
        return to_tasks(raw, origin, path.stem, home)
    except FormatError as exc:
        raise _named(shown, exc) from None


def read_obstacles(path: Path, origin: Origin | None, shown: str | None = None) -> list[ObstacleRecord]:
    """The obstacle polygons in ``path`` (ENU metres)."""
    shown = shown or str(path)
    try:
        reader = reader_for(path)
        return to_obstacles(reader.polygons(reader.parse(read_bounded(path))), origin)
    except FormatError as exc:
        raise _named(shown, exc) from None


RUN_RECORDS = {"plan.json", "plan-collect.json", "summary.json"}  # JSON files a run folder writes itself


def data_files(raw: Any) -> list[str]:
    """The ``{file: PATH}`` paths of a parsed mission mapping (as written)."""
    if not isinstance(raw, dict):
        return []
    refs = [raw.get(k) for k in ("tasks", "obstacles")]
    return [r["file"] for r in refs if isinstance(r, dict) and isinstance(r.get("file"), str)]


def copy_data_files(mission: Any, dest: Path) -> list[Path]:
    """Copy the task/obstacle files of ``mission`` (a :class:`~fleetctl.mission.Mission` read from a
    file) into ``dest`` at the same relative paths, so a copy of the mission file in ``dest`` (the
    run folder's mission.yaml, which ``fleetctl resume`` loads) reads the same data. Absolute paths
    need no copy; a path that leaves the mission's folder (``..``) cannot be mirrored and is
    logged, and so is a data file named like one of the run's own JSON records (plan.json, ...)."""
    if mission.path is None:
        return []
    out = []
    for name in data_files(mission.raw):
        rel = Path(name)
        if rel.is_absolute():
            continue
        if ".." in rel.parts or rel.as_posix() in RUN_RECORDS:
            log.warning("%s is outside the mission's folder or named like a run record: not copied into %s",
                        name, dest)
            continue
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(Path(mission.path).parent / rel, target)
        out.append(target)
    return out


__all__ = ["READERS", "FormatError", "ObstacleRecord", "Reader", "TaskRecord", "copy_data_files",
           "data_files",
           "read_obstacles", "read_tasks", "reader_for"]
