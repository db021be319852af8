"""GeoJSON (RFC 7946, ``.geojson``/``.json``): read tasks and obstacles, write a plan for a map.

Reading: a FeatureCollection (or one Feature). ``Point`` features are tasks, ``Polygon`` and
``MultiPolygon`` features obstacles (outer rings only: a hole stays part of the obstacle, the safe
side). Positions are ``[longitude, latitude(, altitude)]`` in WGS84 degrees as RFC 7946 says - a
file written ``[lat, lon]`` is refused with a hint - and the altitude is in metres in the datum of
the mission's ``origin.alt``: z = alt - origin.alt; no altitude = on the ground. A task's id is
``properties.id``, else ``properties.name``, else the Feature's ``id``, else generated.
A feature whose ``properties.kind`` is set to anything but ``task`` (for tasks) or ``obstacle``
(for obstacles) is skipped: the export's ``plan.geojson`` reads back as its tasks and obstacles.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from fleetctl.mission.formats.common import (
    FormatError,
    RawPoint,
    RawPolygon,
    Vec2,
    check_count,
    decode,
    number,
    open_ring,
    parse_json,
)


def parse(raw: bytes) -> Any:
    """The file's bytes as the document :func:`points` and :func:`polygons` read."""
    return parse_json(decode(raw))


_CRS84 = ("urn:ogc:def:crs:OGC:1.3:CRS84", "urn:ogc:def:crs:OGC::CRS84", "EPSG:4326",
          "urn:ogc:def:crs:EPSG::4326")


def _features(doc: Any) -> list[Any]:
    if not isinstance(doc, dict) or doc.get("type") not in ("FeatureCollection", "Feature"):
        got = doc.get("type") if isinstance(doc, dict) else type(doc).__name__
        raise FormatError("type", f"expected a GeoJSON FeatureCollection or Feature, got {got!r}")
    crs = doc.get("crs")
    if crs is not None:
        name = crs.get("properties", {}).get("name") if isinstance(crs, dict) else None
        if name not in _CRS84:
            raise FormatError("crs", f"coordinate reference system {name!r}: only WGS84 longitude/latitude "
                                     "(RFC 7946) can be read; export the layer as EPSG:4326")
    feats = doc.get("features") if doc["type"] == "FeatureCollection" else [doc]
    if not isinstance(feats, list):
        raise FormatError("features", "expected a list of Features")
    check_count(len(feats), "features")
    return feats


def _geometry(f: Any, where: str) -> tuple[str | None, Any, dict[str, Any]]:
    if not isinstance(f, dict) or f.get("type") != "Feature":
        raise FormatError(where, "expected a Feature {type: Feature, geometry, properties}")
    geom, props = f.get("geometry"), f.get("properties") or {}
    if not isinstance(props, dict):
        raise FormatError(where, "properties must be an object or null")
    if geom is None:
        return None, None, props
    if not isinstance(geom, dict) or not isinstance(geom.get("type"), str):
        raise FormatError(where, "geometry must be a GeoJSON geometry object or null")
    return geom["type"], geom.get("coordinates"), props


def position(c: Any, where: str) -> tuple[float, float, float | None]:
    """An RFC 7946 position [lon, lat(, alt)] → (lat, lon, alt or None)."""
    if not isinstance(c, list) or not 2 <= len(c) <= 3:
        raise FormatError(where, "a position is [longitude, latitude] or [longitude, latitude, altitude]")
    lon = number(c[0], where, "longitude (first value)")
    lat = number(c[1], where, "latitude (second value)")
    alt = number(c[2], where, "altitude (third value)") if len(c) == 3 else None
    return lat, lon, alt


def _feature_id(f: dict[str, Any], props: dict[str, Any], where: str) -> str | None:
    for v in (props.get("id"), props.get("name"), f.get("id")):
        if isinstance(v, bool) or v is None:
            continue
        if isinstance(v, str | int | float):
            return str(v)
        raise FormatError(where, f"the id {v!r:.40} must be a string or a number")
    return None


def _kind_skips(props: dict[str, Any], wanted: str) -> bool:
    return "kind" in props and props["kind"] != wanted


def _summary(seen: dict[str, int]) -> str:
    return ", ".join(f"{n} {t}" for t, n in sorted(seen.items())) or "no features"


def points(doc: Any) -> tuple[list[RawPoint], None]:
    out: list[RawPoint] = []
    seen: dict[str, int] = {}
    for i, f in enumerate(_features(doc)):
        where = f"features[{i}]"
        gtype, coords, props = _geometry(f, where)
        seen[str(gtype)] = seen.get(str(gtype), 0) + 1
        if gtype != "Point" or _kind_skips(props, "task"):
            continue
        lat, lon, alt = position(coords, where + ".geometry.coordinates")
        out.append(RawPoint(where, _feature_id(f, props, where), lat, lon, alt=alt))
    if not out:
        raise FormatError("features", f"no Point feature to read as a task ({_summary(seen)}); "
                                      "draw each task as a Point (kind, when given, must be 'task')")
    return out, None


def _ring(ring: Any, where: str) -> tuple[Vec2, ...]:
    if not isinstance(ring, list) or len(ring) < 4:
        raise FormatError(where, "a polygon ring lists at least 4 positions (the first repeated last)")
    check_count(len(ring), "vertices")
    return open_ring([position(c, f"{where}[{j}]")[:2] for j, c in enumerate(ring)])


def _outer_rings(gtype: str, coords: Any, where: str) -> list[tuple[Vec2, ...]]:
    where += ".geometry.coordinates"
    polys = [coords] if gtype == "Polygon" else coords
    if not isinstance(polys, list) or (gtype == "MultiPolygon" and not polys):
        raise FormatError(where, f"malformed {gtype} coordinates")
    rings = []
    for k, poly in enumerate(polys):
        at = where if gtype == "Polygon" else f"{where}[{k}]"
        if not isinstance(poly, list) or not poly:
            raise FormatError(at, "a polygon is a list of rings, the outer ring first")
        rings.append(_ring(poly[0], f"{at}[0]"))
    return rings


def polygons(doc: Any) -> list[RawPolygon]:
    out: list[RawPolygon] = []
    seen: dict[str, int] = {}
    for i, f in enumerate(_features(doc)):
        where = f"features[{i}]"
        gtype, coords, props = _geometry(f, where)
        seen[str(gtype)] = seen.get(str(gtype), 0) + 1
        if gtype not in ("Polygon", "MultiPolygon") or _kind_skips(props, "obstacle"):
            continue
        rings = _outer_rings(gtype, coords, where)
        out += [RawPolygon(where if len(rings) == 1 else f"{where} polygon {k}", latlon=r)
                for k, r in enumerate(rings)]
    if not out:
        raise FormatError("features", f"no Polygon feature to read as an obstacle ({_summary(seen)}); "
                                      "draw each obstacle as a Polygon")
    return out


# --------------------------------------------------------------------------- writing


def feature(geometry: dict[str, Any], **properties: Any) -> dict[str, Any]:
    return {"type": "Feature", "geometry": geometry, "properties": properties}


def point(lat: float, lon: float, alt: float | None = None) -> dict[str, Any]:
    return {"type": "Point", "coordinates": [lon, lat] if alt is None else [lon, lat, alt]}


def line(latlonalt: Sequence[Sequence[float]]) -> dict[str, Any]:
    return {"type": "LineString", "coordinates": [[p[1], p[0], p[2]] for p in latlonalt]}


def polygon(latlon: Sequence[Vec2]) -> dict[str, Any]:
    ring = [[lon, lat] for lat, lon in latlon]
    return {"type": "Polygon", "coordinates": [ring + ring[:1]]}


def collection(features: Sequence[dict[str, Any]], **members: Any) -> dict[str, Any]:
    return {"type": "FeatureCollection", **members, "features": list(features)}


__all__ = ["collection", "feature", "line", "parse", "point", "points", "polygon", "polygons", "position"]
