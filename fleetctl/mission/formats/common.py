"""What every reader shares: the raw rows a file gives, their conversion to the mission's ENU
frame (through :mod:`fleetctl.geo` only), bounded reading and the error type.

A reader turns a file into :class:`RawPoint` / :class:`RawPolygon` rows exactly as the file says
them (WGS84 degrees and an altitude in a stated reference, or ENU metres); :func:`to_tasks` and
:func:`to_obstacles` convert them with the mission's origin. The loader then validates the result
like a list written in the mission file.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import fleetctl.mission.limits as L
from fleetctl.geo import Origin, geodetic_to_local

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]


class FormatError(ValueError):
    """A task or obstacle file the loader cannot use; the message names where and what to change.

    Readers raise it with ``where`` (``features[3]``, ``line 7``, ``mission.items[2]``) and the
    dispatcher puts the file name in front."""

    def __init__(self, where: str, message: str) -> None:
        super().__init__(f"{where}: {message}" if where else message)
        self.where = where
        self.message = message


@dataclass(frozen=True)
class RawPoint:
    """A task as a file gives it: ``xyz`` (ENU metres, z above ground) or ``lat``/``lon`` with
    either ``alt`` (metres, the datum of the mission's ``origin.alt``) or ``height`` (metres above
    the ground, the mission's z); neither = on the ground."""

    where: str
    id: str | None
    lat: float | None = None
    lon: float | None = None
    alt: float | None = None
    height: float | None = None
    xyz: Vec3 | None = None


@dataclass(frozen=True)
class RawPolygon:
    """An obstacle outline as a file gives it: ``latlon`` vertices, ``xy`` (ENU metres) or a
    ``circle`` (lat, lon, radius in metres)."""

    where: str
    latlon: tuple[Vec2, ...] = ()
    xy: tuple[Vec2, ...] = ()
    circle: Vec3 | None = None


@dataclass(frozen=True)
class TaskRecord:
    where: str
    id: str
    position: Vec3


@dataclass(frozen=True)
class ObstacleRecord:
    where: str
    vertices: tuple[Vec2, ...]


def read_bounded(path: Path) -> bytes:
    """The file's bytes, refused past :data:`~fleetctl.mission.limits.MAX_DATA_FILE_BYTES`."""
    try:
        with path.open("rb") as f:
            raw = f.read(L.MAX_DATA_FILE_BYTES + 1)
    except OSError as exc:
        raise FormatError("", f"cannot read the file: {exc.strerror or exc}; check the path "
                              "(relative paths start at the mission file's folder)") from None
    if len(raw) > L.MAX_DATA_FILE_BYTES:
        raise FormatError("", f"the file is larger than {L.MAX_DATA_FILE_BYTES} bytes; keep only the "
                              "tasks or obstacles of this mission in it")
    return raw


def decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FormatError("", f"not UTF-8 text (byte {exc.start}); save the file as UTF-8") from None


def parse_json(text: str) -> Any:
    """JSON text (strict: no NaN/Infinity), refused with its line and column when malformed."""

    def no_constant(name: str) -> Any:
        raise ValueError(f"{name} is not a JSON number")

    try:
        return json.loads(text, parse_constant=no_constant)
    except json.JSONDecodeError as exc:
        raise FormatError(f"line {exc.lineno} column {exc.colno}", f"malformed JSON: {exc.msg}; "
                                                                   "fix the syntax there") from None
    except RecursionError:
        raise FormatError("", "JSON nested too deeply; a task or obstacle file needs a few levels") from None
    except ValueError as exc:
        raise FormatError("", f"malformed JSON: {exc}") from None


def check_count(n: int, what: str) -> None:
    if n > L.MAX_DATA_FILE_ENTRIES:
        raise FormatError("", f"{n} {what} are too many; a file may hold at most {L.MAX_DATA_FILE_ENTRIES} "
                              "(see docs/mission-limits.md)")


def number(v: object, where: str, what: str) -> float:
    """A finite JSON/text number (bool is not one)."""
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise FormatError(where, f"{what} must be a finite number, got {v!r:.40}")
    return float(v)


# --------------------------------------------------------------------------- conversion to ENU


def _needs_origin(where: str, home: Vec3 | None) -> FormatError:
    hint = ""
    if home is not None:
        hint = (f" (this plan's planned home is lat {home[0]:.7f}, lon {home[1]:.7f}, alt {home[2]:g}: "
                "use it if the carrier starts there)")
    return FormatError(where, "lat/lon positions need the mission's 'origin: {lat, lon, alt}'; add an "
                              f"origin to the mission file{hint}, or give x/y in ENU metres (CSV id,x,y,z)")


def _far(lat: float, lon: float, origin: Origin) -> float:
    x, y, _z = geodetic_to_local(lat, lon, origin.alt, origin)
    return math.hypot(x, y)


def _check_latlon(lat: float, lon: float, where: str, origin: Origin) -> None:
    """Refuse out-of-range or far-away coordinates, with a hint when they look swapped."""
    swapped_ok = -90.0 <= lon <= 90.0 and -180.0 <= lat <= 180.0
    hint = ""
    if swapped_ok and _far(lon, lat, origin) <= L.MAX_COORD:
        hint = ("; latitude and longitude look swapped (the other way round they lie near the origin): "
                "GeoJSON and KML write longitude first ([lon, lat, alt]); in a CSV check the lat/lon columns")
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise FormatError(where, f"latitude {lat:g} / longitude {lon:g} is not a position on Earth "
                                 f"(latitude -90..90, longitude -180..180){hint}")
    d = _far(lat, lon, origin)
    if d > L.MAX_COORD:
        raise FormatError(where, f"lat {lat:.7f}, lon {lon:.7f} lies {d / 1000:.0f} km from the mission's "
                                 f"origin, farther than {L.MAX_COORD / 1000:g} km"
                                 f"{hint or '; check the origin'}")


def to_position(p: RawPoint, origin: Origin | None, home: Vec3 | None = None) -> Vec3:
    """A raw point in the mission frame: ENU x, y; z = height above the origin's altitude."""
    if p.xyz is not None:
        return p.xyz
    assert p.lat is not None and p.lon is not None
    if origin is None:
        raise _needs_origin(p.where, home)
    _check_latlon(p.lat, p.lon, p.where, origin)
    if p.height is not None:
        z = p.height
    elif p.alt is not None:
        z = p.alt - origin.alt
    else:
        z = 0.0
    return geodetic_to_local(p.lat, p.lon, origin.alt + z, origin)


def to_tasks(points: Sequence[RawPoint], origin: Origin | None, stem: str,
             home: Vec3 | None = None) -> list[TaskRecord]:
    """ENU tasks; a point without an id gets ``<file stem>-<n>`` (n counts the file's tasks from 1)."""
    return [TaskRecord(p.where, p.id or f"{stem}-{n}", to_position(p, origin, home))
            for n, p in enumerate(points, 1)]


def to_obstacles(polys: Sequence[RawPolygon], origin: Origin | None) -> list[ObstacleRecord]:
    out = []
    for poly in polys:
        if poly.xy:
            out.append(ObstacleRecord(poly.where, poly.xy))
            continue
        if origin is None:
            raise _needs_origin(poly.where, None)
        if poly.circle is not None:
            out.append(ObstacleRecord(poly.where, _circle(poly.circle, poly.where, origin)))
            continue
        pts = []
        for lat, lon in poly.latlon:
            _check_latlon(lat, lon, poly.where, origin)
            x, y, _z = geodetic_to_local(lat, lon, origin.alt, origin)
            pts.append((x, y))
        out.append(ObstacleRecord(poly.where, tuple(pts)))
    return out


CIRCLE_VERTICES = 16


def _circle(c: Vec3, where: str, origin: Origin) -> tuple[Vec2, ...]:
    """The regular polygon around a circle (its edges touch the circle: the obstacle never shrinks)."""
    lat, lon, radius = c
    _check_latlon(lat, lon, where, origin)
    x, y, _z = geodetic_to_local(lat, lon, origin.alt, origin)
    r = radius / math.cos(math.pi / CIRCLE_VERTICES)
    return tuple((x + r * math.cos(2 * math.pi * k / CIRCLE_VERTICES),
                  y + r * math.sin(2 * math.pi * k / CIRCLE_VERTICES)) for k in range(CIRCLE_VERTICES))


def open_ring(ring: Sequence[Vec2]) -> tuple[Vec2, ...]:
    """A polygon ring without its closing vertex (GeoJSON and KML repeat the first vertex)."""
    pts = tuple(ring)
    return pts[:-1] if len(pts) > 1 and pts[0] == pts[-1] else pts


__all__ = ["FormatError", "ObstacleRecord", "RawPoint", "RawPolygon", "TaskRecord", "check_count", "decode",
           "number", "open_ring", "parse_json", "read_bounded", "to_obstacles", "to_position", "to_tasks"]
