"""QGroundControl plan files (``.plan``, JSON): read tasks and obstacles, write a vehicle's mission.

QGroundControl documents the format in its developer guide ("Plan File Format"): a JSON object
``{fileType: "Plan", version: 1, groundStation, mission, geoFence, rallyPoints}``; ``mission.items``
are ``SimpleItem`` objects (a MAVLink mission item: ``command``, ``frame``, ``params[7]`` with
latitude, longitude and altitude in ``params[4..6]``) or ``ComplexItem`` (surveys and the like).

Reading (``tasks: {file: X.plan}``): every ``SimpleItem`` with command 16 (``MAV_CMD_NAV_WAYPOINT``)
is a task; its altitude by its frame:

* 0 / 5 ``GLOBAL`` (AMSL): z = alt - origin.alt (the same datum as the mission's origin altitude,
  as in the controller's own mission items);
* 3 / 6 ``GLOBAL_RELATIVE_ALT`` (above home): z = alt + plannedHomePosition's altitude - origin.alt;
  without a planned home altitude, above the origin's altitude (the controller's own convention);
* 10 / 11 ``GLOBAL_TERRAIN_ALT`` and any other frame: refused (no terrain model here).

Other commands (take-off, loiter, land, ...) and complex items are not tasks and are skipped.
``obstacles: {file: X.plan}`` reads the geofence's exclusion polygons and exclusion circles (a
circle becomes the 16-gon around it); inclusion zones are not obstacles and are skipped.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from fleetctl.mission.formats.common import (
    FormatError,
    RawPoint,
    RawPolygon,
    Vec2,
    Vec3,
    check_count,
    decode,
    number,
    parse_json,
)

if TYPE_CHECKING:
    from fleetctl.mavlink.link import MissionItem

NAV_WAYPOINT = 16
AMSL_FRAMES = {0: "GLOBAL", 5: "GLOBAL_INT"}
RELATIVE_FRAMES = {3: "GLOBAL_RELATIVE_ALT", 6: "GLOBAL_RELATIVE_ALT_INT"}
TERRAIN_FRAMES = {10: "GLOBAL_TERRAIN_ALT", 11: "GLOBAL_TERRAIN_ALT_INT"}
# .plan files hold the float frames; a MISSION_ITEM_INT's _INT frame is written as its float twin
FLOAT_FRAME = {5: 0, 6: 3, 11: 10}
ALTITUDE_MODE = {0: 2, 3: 1, 10: 4}  # QGroundControl AltitudeMode: 1 relative, 2 AMSL, 4 terrain frame
MAV_AUTOPILOT = {"px4": 12, "ardupilot": 3, "generic": 0}


# --------------------------------------------------------------------------- reading
def parse(raw: bytes) -> Any:
    """The file's bytes as the document :func:`points` and :func:`polygons` read."""
    return parse_json(decode(raw))



def _document(doc: Any) -> dict[str, Any]:
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        got = doc.get("fileType") if isinstance(doc, dict) else type(doc).__name__
        raise FormatError("fileType", f"not a QGroundControl plan (fileType {got!r}, expected 'Plan'); "
                                      "save the mission from QGroundControl's Plan view (File > Save)")
    return doc


def planned_home(doc: Any) -> Vec3 | None:
    """``mission.plannedHomePosition`` as (lat, lon, alt), or None when absent."""
    mission = _document(doc).get("mission")
    home = mission.get("plannedHomePosition") if isinstance(mission, dict) else None
    if home is None:
        return None
    if not isinstance(home, list) or len(home) != 3:
        raise FormatError("mission.plannedHomePosition", "expected [lat, lon, alt]")
    lat, lon, alt = (number(v, "mission.plannedHomePosition", "each value") for v in home)
    return (lat, lon, alt)


def points(doc: Any) -> tuple[list[RawPoint], Vec3 | None]:
    """The plan's NAV_WAYPOINT items as raw tasks, and its planned home."""
    mission = _document(doc).get("mission")
    items = mission.get("items") if isinstance(mission, dict) else None
    if not isinstance(items, list):
        raise FormatError("mission.items", "missing: the plan has no mission item list")
    check_count(len(items), "mission items")
    home = planned_home(doc)
    out = [p for i, item in enumerate(items) if (p := _item_point(item, i, home)) is not None]
    if not out:
        raise FormatError("mission.items", f"none of the {len(items)} items is a waypoint (SimpleItem with "
                                           "command 16, MAV_CMD_NAV_WAYPOINT); add waypoints at the tasks")
    return out, home


def _item_point(item: Any, i: int, home: Vec3 | None) -> RawPoint | None:
    where = f"mission.items[{i}]"
    if not isinstance(item, dict):
        raise FormatError(where, "expected a mission item object")
    if item.get("type") != "SimpleItem" or item.get("command") != NAV_WAYPOINT:
        return None
    params = item.get("params")
    if not isinstance(params, list) or len(params) != 7:
        raise FormatError(where, "params must be a list of 7 values "
                                 "(param1..4, latitude, longitude, altitude)")
    lat = number(params[4], where, "params[4] (latitude)")
    lon = number(params[5], where, "params[5] (longitude)")
    alt = number(params[6], where, "params[6] (altitude)")
    frame = item.get("frame")
    if isinstance(frame, bool) or not isinstance(frame, int):
        raise FormatError(where, f"frame must be a MAV_FRAME number, got {frame!r:.40}")
    if frame in AMSL_FRAMES:
        return RawPoint(where, None, lat, lon, alt=alt)
    if frame in RELATIVE_FRAMES:
        if home is not None:
            return RawPoint(where, None, lat, lon, alt=alt + home[2])
        return RawPoint(where, None, lat, lon, height=alt)
    if frame in TERRAIN_FRAMES:
        raise FormatError(where, f"frame {frame} ({TERRAIN_FRAMES[frame]}) gives the altitude above the "
                                 "terrain, which cannot be converted without a terrain model; set the "
                                 "waypoint's altitude mode to Relative or AMSL in QGroundControl")
    raise FormatError(where, f"frame {frame!r} is not a global frame with latitude/longitude; use 0 "
                             "(GLOBAL, AMSL) or 3 (GLOBAL_RELATIVE_ALT)")


def polygons(doc: Any) -> list[RawPolygon]:
    """The geofence's exclusion polygons and circles as raw obstacles."""
    fence = _document(doc).get("geoFence")
    if not isinstance(fence, dict):
        raise FormatError("geoFence", "missing: the plan has no geofence to read obstacles from")
    if "polygon" in fence or fence.get("version") == 1:
        raise FormatError("geoFence", "an old (version 1) geofence; open the plan in a current "
                                      "QGroundControl and save it again")
    polys, circles = fence.get("polygons", []), fence.get("circles", [])
    if not isinstance(polys, list) or not isinstance(circles, list):
        raise FormatError("geoFence", "polygons and circles must be lists")
    check_count(len(polys) + len(circles), "geofence shapes")
    out = [p for i, f in enumerate(polys) if (p := _fence_polygon(f, i)) is not None]
    out += [c for i, f in enumerate(circles) if (c := _fence_circle(f, i)) is not None]
    if not out:
        raise FormatError("geoFence", "no exclusion zone (inclusion: false) in the geofence; draw the "
                                      "obstacles as exclusion polygons in QGroundControl")
    return out


def _fence_polygon(f: Any, i: int) -> RawPolygon | None:
    where = f"geoFence.polygons[{i}]"
    if not isinstance(f, dict) or not isinstance(f.get("polygon"), list):
        raise FormatError(where, "expected {inclusion, polygon: [[lat, lon], ...], version}")
    if f.get("inclusion", True):
        return None
    check_count(len(f["polygon"]), "vertices")
    pts = []
    for j, v in enumerate(f["polygon"]):
        if not isinstance(v, list) or len(v) != 2:
            raise FormatError(f"{where}.polygon[{j}]", "expected [lat, lon]")
        pts.append((number(v[0], where, "latitude"), number(v[1], where, "longitude")))
    return RawPolygon(where, latlon=tuple(pts))


def _fence_circle(f: Any, i: int) -> RawPolygon | None:
    where = f"geoFence.circles[{i}]"
    circle = f.get("circle") if isinstance(f, dict) else None
    center = circle.get("center") if isinstance(circle, dict) else None
    if not isinstance(circle, dict) or not isinstance(center, list) or len(center) != 2:
        raise FormatError(where, "expected {circle: {center: [lat, lon], radius}, inclusion, version}")
    if f.get("inclusion", True):
        return None
    lat, lon = (number(v, where, "circle.center") for v in center)
    radius = number(circle.get("radius"), where, "circle.radius (metres)")
    if radius <= 0:
        raise FormatError(where, f"circle.radius {radius:g} must be > 0 metres")
    return RawPolygon(where, circle=(lat, lon, radius))


# --------------------------------------------------------------------------- writing


def _param(v: float) -> float | None:
    return None if math.isnan(v) else float(v)


def simple_item(item: MissionItem, seq: int) -> dict[str, Any]:
    """One compiled mission item as a QGroundControl SimpleItem (``doJumpId`` counts from 1)."""
    frame = FLOAT_FRAME.get(item.frame, item.frame)
    params = [item.param1, item.param2, item.param3, item.param4, item.lat, item.lon, item.z]
    return {
        "AMSLAltAboveTerrain": None,
        "Altitude": float(item.z),
        "AltitudeMode": ALTITUDE_MODE.get(frame, 1),
        "autoContinue": bool(item.autocontinue),
        "command": int(item.command),
        "doJumpId": seq,
        "frame": int(frame),
        "params": [_param(float(p)) for p in params],
        "type": "SimpleItem",
    }


def plan_document(
    items: Sequence[MissionItem], *, home: Vec3, firmware_type: int, vehicle_type: int, cruise_speed: float,
    hover_speed: float, exclusions: Sequence[Sequence[Vec2]] = (), inclusion: Sequence[Vec2] | None = None,
) -> dict[str, Any]:
    """A whole ``.plan`` document for one vehicle: its mission items in upload order, the planned
    home (lat, lon, alt AMSL) and the geofence polygons (lists of (lat, lon))."""
    zones = [(True, inclusion)] if inclusion else []
    zones += [(False, poly) for poly in exclusions]
    fence = [{"inclusion": inc, "polygon": [[a, b] for a, b in poly], "version": 1} for inc, poly in zones]
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "fleetctl",
        "mission": {
            "version": 2,
            "firmwareType": firmware_type,
            "vehicleType": vehicle_type,
            "cruiseSpeed": cruise_speed,
            "hoverSpeed": hover_speed,
            "globalPlanAltitudeMode": 1,
            "plannedHomePosition": [home[0], home[1], home[2]],
            "items": [simple_item(it, seq) for seq, it in enumerate(items, 1)],
        },
        "geoFence": {"version": 2, "circles": [], "polygons": fence},
        "rallyPoints": {"version": 2, "points": []},
    }


__all__ = ["MAV_AUTOPILOT", "parse", "plan_document", "planned_home", "points", "polygons", "simple_item"]
