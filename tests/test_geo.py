"""fleetctl.geo: WGS84 ↔ ENU round trips and compass ↔ math headings."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleetctl.geo import (
    Origin,
    compass_to_math,
    enu_to_geodetic,
    geodetic_to_enu,
    geodetic_to_local,
    local_to_geodetic,
    math_to_compass,
)

ORIGIN = Origin(47.397742, 8.545594, 488.0)
MM = 1e-3

origins = st.builds(
    Origin,
    lat=st.floats(-85.0, 85.0),
    lon=st.floats(-180.0, 180.0),
    alt=st.floats(-400.0, 9000.0),
)
offsets = st.floats(-10_000.0, 10_000.0)
heights = st.floats(-500.0, 2_000.0)


def test_origin_maps_to_zero() -> None:
    assert geodetic_to_enu(ORIGIN.lat, ORIGIN.lon, ORIGIN.alt, ORIGIN) == pytest.approx((0, 0, 0), abs=1e-9)


def test_known_offsets() -> None:
    # 0.001° of latitude is about 111.2 m north at 47.4° N; 0.001° of longitude about 75.4 m east
    e, n, _ = geodetic_to_enu(ORIGIN.lat + 0.001, ORIGIN.lon, ORIGIN.alt, ORIGIN)
    assert e == pytest.approx(0.0, abs=1e-6) and n == pytest.approx(111.2, abs=0.2)
    e, n, _ = geodetic_to_enu(ORIGIN.lat, ORIGIN.lon + 0.001, ORIGIN.alt, ORIGIN)
    assert e == pytest.approx(75.4, abs=0.2) and abs(n) < 0.01


@settings(max_examples=300, deadline=None)
@given(origin=origins, x=offsets, y=offsets, z=heights)
def test_enu_geodetic_enu_round_trip_within_a_millimetre(
    origin: Origin, x: float, y: float, z: float
) -> None:
    lat, lon, alt = enu_to_geodetic(x, y, z, origin)
    back = geodetic_to_enu(lat, lon, alt, origin)
    assert math.dist(back, (x, y, z)) < MM


@settings(max_examples=300, deadline=None)
@given(origin=origins, x=offsets, y=offsets, z=heights)
def test_wgs84_enu_wgs84_round_trip_within_a_millimetre(origin: Origin, x: float, y: float, z: float) -> None:
    # a random WGS84 point within 10 km of the origin, then WGS84 → ENU → WGS84
    lat, lon, alt = enu_to_geodetic(x, y, z, origin)
    lat2, lon2, alt2 = enu_to_geodetic(*geodetic_to_enu(lat, lon, alt, origin), origin)
    # compare in metres: the ENU offset between the two geodetic points
    assert math.dist(geodetic_to_enu(lat2, lon2, alt2, origin), geodetic_to_enu(lat, lon, alt, origin)) < MM
    assert abs(alt2 - alt) < MM


@settings(max_examples=200, deadline=None)
@given(origin=origins, x=offsets, y=offsets, z=heights)
def test_local_frame_round_trip(origin: Origin, x: float, y: float, z: float) -> None:
    lat, lon, alt = local_to_geodetic(x, y, z, origin)
    assert alt == pytest.approx(origin.alt + z, abs=1e-9)
    assert math.dist(geodetic_to_local(lat, lon, alt, origin), (x, y, z)) < MM


def test_local_z_is_height_above_origin_altitude() -> None:
    # 5 km east the ENU up axis has left the local vertical: the ENU z of a point at the origin's
    # altitude is about -2 m (curvature), while the mission frame keeps z = alt - origin.alt = 0
    lat, lon, alt = local_to_geodetic(5000.0, 0.0, 0.0, ORIGIN)
    assert alt == ORIGIN.alt
    assert geodetic_to_enu(lat, lon, alt, ORIGIN)[2] == pytest.approx(-1.96, abs=0.05)
    assert geodetic_to_local(lat, lon, alt, ORIGIN)[2] == 0.0


@pytest.mark.parametrize(
    ("compass", "rad"),
    [
        (0.0, math.pi / 2),
        (90.0, 0.0),
        (180.0, 3 * math.pi / 2),
        (270.0, math.pi),
        (45.0, math.pi / 4),
        (360.0, math.pi / 2),
        (-90.0, math.pi),
    ],
)
def test_compass_to_math_cardinal_directions(compass: float, rad: float) -> None:
    assert compass_to_math(compass) == pytest.approx(rad, abs=1e-12)


@pytest.mark.parametrize(
    ("rad", "compass"),
    [(0.0, 90.0), (math.pi / 2, 0.0), (math.pi, 270.0), (-math.pi / 2, 180.0), (3 * math.pi / 4, 315.0)],
)
def test_math_to_compass(rad: float, compass: float) -> None:
    assert math_to_compass(rad) == pytest.approx(compass, abs=1e-9)


@given(st.floats(-720.0, 720.0))
def test_heading_round_trip_and_ranges(deg: float) -> None:
    rad = compass_to_math(deg)
    assert 0.0 <= rad < math.tau
    back = math_to_compass(rad)
    assert 0.0 <= back < 360.0
    diff = (back - deg) % 360.0
    assert min(diff, 360.0 - diff) < 1e-9


@given(st.floats(-720.0, 720.0))
def test_compass_heading_points_the_right_way(deg: float) -> None:
    # compass heading θ points to (east, north) = (sin θ, cos θ)
    rad = compass_to_math(deg)
    assert math.cos(rad) == pytest.approx(math.sin(math.radians(deg)), abs=1e-9)
    assert math.sin(rad) == pytest.approx(math.cos(math.radians(deg)), abs=1e-9)
