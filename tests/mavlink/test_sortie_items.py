"""An operation's sortie missions (fleetctl.mavlink.sortie): on an autopilot whose mission ends at a
landing (ArduCopter) a sortie's mission ends at its first task worked on the ground, and the rest
is a mission of its own taking off from that task."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.geo import Origin
from fleetctl.mavlink.autopilots.ardupilot import ArduPilot
from fleetctl.mavlink.autopilots.px4 import Px4
from fleetctl.mavlink.compile import item_position
from fleetctl.mavlink.sortie import Visit, sortie_items
from fleetctl.mission.flight import TAKEOFF_HEIGHT

ORIGIN = Origin(47.397742, 8.545594, 488.0)
VISITS = [Visit("t1", (20.0, 30.0, 4.0), 20.0, False), Visit("t2", (60.0, 40.0, 0.0), 25.0, True),
          Visit("t3", (80.0, 20.0, 4.0), 15.0, False)]


def _commands(items) -> list[int]:  # type: ignore[no-untyped-def]
    return [it.command for it in items]


def test_px4_times_ground_work_with_a_nav_delay_in_one_mission() -> None:
    s = sortie_items("r1", (0.0, 0.0, 0.0), VISITS, ORIGIN, Px4(M.MAV_TYPE_QUADROTOR))
    assert [w.task for w in s.work] == ["t1", "t2", "t3"] and all(w.done_seq >= 0 for w in s.work)
    assert s.items[s.work[1].done_seq].command == M.MAV_CMD_NAV_DELAY


def test_ardupilot_copter_mission_ends_at_the_first_landing() -> None:
    ap = ArduPilot(M.MAV_TYPE_QUADROTOR)
    assert ap.landing_ends_mission and not ArduPilot(M.MAV_TYPE_GROUND_ROVER).landing_ends_mission
    s = sortie_items("r1", (0.0, 0.0, 0.0), VISITS, ORIGIN, ap)
    assert [w.task for w in s.work] == ["t1", "t2"]
    assert s.work[0].done_seq >= 0 and s.work[1].done_seq == -1  # t2's work: timed by the controller
    assert _commands(s.items)[-1] == M.MAV_CMD_NAV_LAND and M.MAV_CMD_NAV_DELAY not in _commands(s.items)
    # the rest: a mission of its own from t2 on the ground (home there, a take-off above it), then t3
    rest = sortie_items("r1", (0.0, 0.0, 0.0), VISITS[2:], ORIGIN, ap, takeoff_from=VISITS[1].position)
    assert [w.task for w in rest.work] == ["t3"] and rest.work[0].done_seq >= 0
    home, takeoff = rest.items[0], rest.items[rest.takeoff_seq]
    assert takeoff.command == M.MAV_CMD_NAV_TAKEOFF and rest.takeoff_seq == 1
    hx, hy, _ = item_position(home, ORIGIN)
    tx, ty, tz = item_position(takeoff, ORIGIN)
    assert abs(hx - 60.0) < 0.01 and abs(hy - 40.0) < 0.01 and abs(tx - 60.0) < 0.01
    assert abs(tz - TAKEOFF_HEIGHT) < 0.01
