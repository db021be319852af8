"""A carrier's arrival at a stop told by its telemetry (fleetctl.run.carrier.stopped_on_item): when
both the MISSION_ITEM_REACHED and the MISSION_CURRENT that tell it at once are lost on a lossy link,
a position stopped on the stop's mission item shows it, while a carrier driving through the stop, or
stopped short of it, has not arrived. The same for a rover's hold above its meeting point
(hovering_on_item): at rest in the air on it, not while it still climbs or descends onto it."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.geo import Origin, local_to_geodetic
from fleetctl.mavlink.link import Link, MissionItem
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.run.carrier import STAY_RADIUS, STAY_SPEED, hovering_on_item, stopped_on_item

ORIGIN = Origin(47.397742, 8.545594, 488.0)


def _item(x: float, y: float) -> MissionItem:
    lat, lon, _alt = local_to_geodetic(x, y, 0.0, ORIGIN)
    return MissionItem(M.MAV_CMD_NAV_WAYPOINT, x=int(round(lat * 1e7)), y=int(round(lon * 1e7)))


def _carrier(x: float, y: float, speed: float) -> Vehicle:
    v = Vehicle(Link("udp://127.0.0.1:9"), 1, name="carrier", origin=ORIGIN)  # never opened
    v.lat, v.lon, v.alt = local_to_geodetic(x, y, 0.0, ORIGIN)
    v.velocity = (speed, 0.0, 0.0)
    v.mission_items = [_item(0.0, 0.0), _item(40.0, 10.0), _item(80.0, 10.0)]
    return v


def test_a_carrier_stopped_on_its_stop_has_arrived() -> None:
    assert stopped_on_item(_carrier(40.2, 10.1, 0.05), 1)
    assert not stopped_on_item(_carrier(40.2, 10.1, 0.05), 2)  # the next stop: not there


def test_driving_through_or_stopped_short_is_not_an_arrival() -> None:
    assert not stopped_on_item(_carrier(40.0, 10.0, 6.0), 1)
    assert not stopped_on_item(_carrier(40.0 - 3 * STAY_RADIUS, 10.0, 0.0), 1)
    v = _carrier(40.0, 10.0, 0.0)
    v.velocity = None  # no speed known yet
    assert not stopped_on_item(v, 1)
    assert not stopped_on_item(_carrier(40.0, 10.0, 0.0), 7)  # no such item


def test_a_carrier_stopped_at_a_vertex_next_to_its_stop_has_not_arrived() -> None:
    """A roadmap path's last vertex may lie within STAY_RADIUS of the stop: the carrier stops there
    too (a rest-to-rest segment), nearer that waypoint than the stop - not an arrival."""
    v = _carrier(39.4, 10.0, 0.0)
    v.mission_items = [_item(0.0, 0.0), _item(39.4, 10.0), _item(40.0, 10.0)]  # a vertex 0.6 m short
    assert not stopped_on_item(v, 2)
    v.lat, v.lon, v.alt = local_to_geodetic(39.9, 10.0, 0.0, ORIGIN)  # then on the stop
    assert stopped_on_item(v, 2)


def test_a_rover_at_rest_on_its_hold_has_arrived_not_one_still_descending() -> None:
    v = _carrier(40.1, 9.9, 0.05)  # a rover's telemetry: same fields
    v.velocity = (0.05, 0.0, -0.05)
    assert hovering_on_item(v, 1)
    v.velocity = (0.05, 0.0, -3 * STAY_SPEED)  # coming down onto the hold height
    assert not hovering_on_item(v, 1)
    v.velocity = (0.0, 0.0, 0.0)
    assert not hovering_on_item(v, 2)  # another item


def test_docs_mavlink_states_the_arrival_rules() -> None:
    from pathlib import Path

    from fleetctl.run.collect import GROUND_SNAP

    text = (Path(__file__).parents[2] / "docs" / "mavlink.md").read_text()
    assert f"stopped (at most {STAY_SPEED:g} m/s) within {STAY_RADIUS:g} m of its stop's item" in text
    assert (f"at rest in the air (at most {STAY_SPEED:g} m/s horizontally and vertically, more than "
            f"{GROUND_SNAP:g} m up) within {STAY_RADIUS:g} m of its hold") in text
