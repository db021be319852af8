"""A world position (metres north, east, down of the origin on the ground) as latitude, longitude
and AMSL altitude, as ArduPilot's ``Location`` offsets compute it: a flat earth of the equatorial
radius around the origin. ArduPilot places a JSON physics position relative to its home that way,
so a vehicle's ``--home`` must be computed the same way. It is not WGS84: 10 m north at 47°
latitude lands 1.5 cm off ``sitl.geo``'s ENU frame (PX4 is sent true WGS84 positions from there)."""

from __future__ import annotations

import math

EARTH_RADIUS = 6378137.0  # m, as ArduPilot's Location offsets


def offset(origin: tuple[float, float, float], north: float, east: float,
           down: float) -> tuple[float, float, float]:
    """(lat, lon, AMSL alt) of the point ``north``, ``east``, ``down`` metres from ``origin``
    (lat, lon, AMSL alt of the ground)."""
    lat0, lon0, alt0 = origin
    lat = lat0 + math.degrees(north / EARTH_RADIUS)
    lon = lon0 + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat0))))
    return lat, lon, alt0 - down
