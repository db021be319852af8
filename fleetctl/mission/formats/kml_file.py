"""KML (``.kml``, Google Earth and most GIS tools): Placemark Points are tasks, Polygons obstacles.

Parsed with :mod:`defusedxml` (no DTD at all: entity expansion bombs and external entities are
refused before anything is read). Coordinates are ``lon,lat[,alt]`` tuples. A Point's altitude
follows its ``altitudeMode``: ``clampToGround`` (the KML default) puts the task on the ground,
``relativeToGround`` gives the height above the ground (the mission's z), ``absolute`` an
altitude in the datum of the mission's ``origin.alt`` (z = alt - origin.alt); the seafloor modes
are refused. A task's id is the Placemark's ``<name>``, else its ``id`` attribute, else generated.
Polygons use their outer boundary (holes stay part of the obstacle).
"""

from __future__ import annotations

from typing import Any
from xml.etree.ElementTree import Element, ParseError

import defusedxml
import defusedxml.ElementTree as SafeET

from fleetctl.mission.formats.common import FormatError, RawPoint, RawPolygon, Vec2, check_count, open_ring


def parse(raw: bytes) -> Element:
    """The KML document's root element, parsed safely."""
    try:
        root: Element = SafeET.fromstring(raw, forbid_dtd=True)
    except defusedxml.DefusedXmlException as exc:
        raise FormatError("", f"refused: the file declares a DTD or entities ({type(exc).__name__}); "
                              "KML needs neither - save it again from the mapping tool") from None
    except ParseError as exc:
        line, col = getattr(exc, "position", (0, 0))
        raise FormatError(f"line {line} column {col}",
                          f"malformed XML: {exc}; fix the syntax there") from None
    except (LookupError, ValueError) as exc:  # an unknown encoding in the XML declaration, bad bytes
        raise FormatError("", f"cannot read the XML: {exc}; save the file as UTF-8") from None
    if _local(root.tag) != "kml":
        raise FormatError("", f"not a KML document (root element <{_local(root.tag)}>, expected <kml>)")
    return root


def _local(tag: Any) -> str:
    return str(tag).rsplit("}", 1)[-1]


def _child(el: Element, name: str) -> Element | None:
    return next((c for c in el if _local(c.tag) == name), None)


def _placemarks(root: Element) -> list[Element]:
    marks = [el for el in root.iter() if _local(el.tag) == "Placemark"]
    check_count(len(marks), "Placemarks")
    return marks


def _coords(el: Element, where: str) -> list[tuple[float, float, float | None]]:
    text = (el.text or "").split()
    check_count(len(text), "coordinates")
    out = []
    for tup in text:
        parts = tup.split(",")
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            raise FormatError(where, f"coordinates {tup!r:.40} are not numbers lon,lat[,alt]") from None
        if not 2 <= len(vals) <= 3 or not all(v == v and abs(v) != float("inf") for v in vals):
            raise FormatError(where, f"coordinates {tup!r:.40}: expected lon,lat or lon,lat,alt")
        out.append((vals[1], vals[0], vals[2] if len(vals) == 3 else None))
    return out


def _name(mark: Element) -> str | None:
    name = _child(mark, "name")
    if name is not None and name.text and name.text.strip():
        return name.text.strip()
    return mark.get("id")


def _point(geom: Element, ident: str | None, where: str) -> RawPoint:
    coords = _child(geom, "coordinates")
    if coords is None:
        raise FormatError(where, "a Point needs <coordinates>lon,lat[,alt]</coordinates>")
    pts = _coords(coords, where)
    if len(pts) != 1:
        raise FormatError(where, f"a Point has one coordinate tuple, got {len(pts)}")
    lat, lon, alt = pts[0]
    mode_el = _child(geom, "altitudeMode")
    mode = (mode_el.text or "").strip() if mode_el is not None else "clampToGround"
    if mode == "clampToGround" or alt is None:
        return RawPoint(where, ident, lat, lon)
    if mode == "relativeToGround":
        return RawPoint(where, ident, lat, lon, height=alt)
    if mode == "absolute":
        return RawPoint(where, ident, lat, lon, alt=alt)
    raise FormatError(where, f"altitudeMode {mode!r} cannot be converted; use clampToGround, "
                             "relativeToGround or absolute")


def points(root: Element) -> tuple[list[RawPoint], None]:
    out = []
    for i, mark in enumerate(_placemarks(root)):
        ident = _name(mark)
        where = f"Placemark[{i}]" + (f" {ident!r}" if ident else "")
        geoms = [g for g in mark.iter() if _local(g.tag) == "Point"]
        if len(geoms) == 1:
            out.append(_point(geoms[0], ident, where))
        else:  # a MultiGeometry of points: one task each, ids generated
            out += [_point(g, None, f"{where}.Point[{k}]") for k, g in enumerate(geoms)]
    if not out:
        raise FormatError("", "no Placemark with a Point to read as a task; mark each task as a Point")
    return out, None


def _outer(poly: Element, where: str) -> tuple[Vec2, ...]:
    outer = _child(poly, "outerBoundaryIs")
    ring = _child(outer, "LinearRing") if outer is not None else None
    coords = _child(ring, "coordinates") if ring is not None else None
    if coords is None:
        raise FormatError(where, "a Polygon needs <outerBoundaryIs><LinearRing><coordinates>")
    return open_ring([(lat, lon) for lat, lon, _alt in _coords(coords, where)])


def polygons(root: Element) -> list[RawPolygon]:
    out = []
    for i, mark in enumerate(_placemarks(root)):
        ident = _name(mark)
        where = f"Placemark[{i}]" + (f" {ident!r}" if ident else "")
        geoms = [g for g in mark.iter() if _local(g.tag) == "Polygon"]
        out += [RawPolygon(where if len(geoms) == 1 else f"{where}.Polygon[{k}]",
                           latlon=_outer(g, where)) for k, g in enumerate(geoms)]
    if not out:
        raise FormatError("", "no Placemark with a Polygon to read as an obstacle; draw each obstacle "
                              "as a Polygon")
    return out


__all__ = ["parse", "points", "polygons"]
