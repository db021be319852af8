"""Geodesy: WGS84 latitude/longitude/altitude ↔ the mission's local ENU frame, and headings.

This is the only module of the project that converts to or from latitude/longitude (docs/mission-file.md,
"Conventions"). The conversions are pymap3d's exact ellipsoidal ones on WGS84, so a round
trip is exact to far below a millimetre.

Two local frames are offered:

* ``geodetic_to_enu`` / ``enu_to_geodetic``: the true local tangent plane (x east, y north, z along
  the ellipsoid normal at the origin).
* ``geodetic_to_local`` / ``local_to_geodetic``: the mission frame for task positions, where x, y
  are the ENU east/north of the point and z is its height above the origin's altitude,
  ``alt - origin.alt`` (what autopilots call relative altitude). It differs from the ENU up by
  the Earth's curvature (about 8 cm at 1 km from the origin, 8 m at 10 km).

Headings: mission files use compass degrees (0 = north, 90 = east, clockwise); planners use math
radians (0 = east, counter-clockwise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pymap3d

WGS84 = pymap3d.Ellipsoid.from_name("wgs84")


@dataclass(frozen=True)
class Origin:
    """The WGS84 point (degrees, degrees, metres above the ellipsoid) at the ENU frame's origin."""

    lat: float
    lon: float
    alt: float


def geodetic_to_enu(lat: float, lon: float, alt: float, origin: Origin) -> tuple[float, float, float]:
    """WGS84 (degrees, metres) → ENU metres (east, north, up) relative to ``origin``."""
    e, n, u = pymap3d.geodetic2enu(lat, lon, alt, origin.lat, origin.lon, origin.alt, ell=WGS84, deg=True)
    return float(e), float(n), float(u)


def enu_to_geodetic(x: float, y: float, z: float, origin: Origin) -> tuple[float, float, float]:
    """ENU metres relative to ``origin`` → WGS84 (lat degrees, lon degrees, alt metres)."""
    lat, lon, alt = pymap3d.enu2geodetic(x, y, z, origin.lat, origin.lon, origin.alt, ell=WGS84, deg=True)
    return float(lat), float(lon), float(alt)


def geodetic_to_local(lat: float, lon: float, alt: float, origin: Origin) -> tuple[float, float, float]:
    """WGS84 → mission frame: ENU east/north of the point, z = ``alt - origin.alt``."""
    e, n, _ = geodetic_to_enu(lat, lon, alt, origin)
    return e, n, alt - origin.alt


def local_to_geodetic(x: float, y: float, z: float, origin: Origin) -> tuple[float, float, float]:
    """Inverse of :func:`geodetic_to_local`: the WGS84 point at altitude ``origin.alt + z`` whose
    ENU east/north are ``(x, y)``.

    The east/north of a point depend slightly on its altitude (the ENU up axis is not the local
    vertical away from the origin), so the horizontal position is found by a few fixed-point
    corrections; each one shrinks the error by a factor of about ``distance / earth radius``.
    """
    alt = origin.alt + z
    ex, ey = x, y
    lat = lon = 0.0
    for _ in range(8):
        lat, lon, _alt = enu_to_geodetic(ex, ey, z, origin)
        e, n, _u = geodetic_to_enu(lat, lon, alt, origin)
        dx, dy = x - e, y - n
        if abs(dx) < 1e-7 and abs(dy) < 1e-7:
            break
        ex, ey = ex + dx, ey + dy
    return lat, lon, alt


def compass_to_math(deg: float) -> float:
    """Compass heading in degrees (0 = north, 90 = east) → math angle in radians in [0, 2π)."""
    rad = math.radians(90.0 - deg) % math.tau
    return 0.0 if rad >= math.tau else rad


def math_to_compass(rad: float) -> float:
    """Math angle in radians (0 = east, counter-clockwise) → compass degrees in [0, 360)."""
    deg = (90.0 - math.degrees(rad)) % 360.0
    return 0.0 if deg >= 360.0 else deg
