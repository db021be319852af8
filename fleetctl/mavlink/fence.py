"""Geofence as MAVLink: the FENCE mission (``mission_type`` FENCE) of an inclusion polygon and
exclusion polygons, uploaded and read back with the mission protocol (docs/mavlink.md).

Each vertex is a ``MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION`` (or ``_EXCLUSION``) item in
``MAV_FRAME_GLOBAL`` whose ``param1`` is its polygon's vertex count; polygons follow each other.
"""

from __future__ import annotations

from collections.abc import Sequence

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.geo import Origin, local_to_geodetic
from fleetctl.mavlink.link import MissionItem

M = mavlink2
FENCE = M.MAV_MISSION_TYPE_FENCE
Polygon = Sequence[tuple[float, float]]  # ENU metres


def fence_items(inclusion: Polygon, exclusions: Sequence[Polygon], origin: Origin) -> list[MissionItem]:
    """The FENCE mission: the inclusion polygon, then one exclusion polygon each."""
    items: list[MissionItem] = []
    zones = [(M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, inclusion)]
    zones += [(M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION, pts) for pts in exclusions]
    for command, pts in zones:
        for x, y in pts:
            lat, lon, _alt = local_to_geodetic(x, y, 0.0, origin)
            items.append(MissionItem(command, M.MAV_FRAME_GLOBAL, param1=float(len(pts)),
                                     x=int(round(lat * 1e7)), y=int(round(lon * 1e7))))
    return items


__all__ = ["FENCE", "fence_items"]
