"""What a long operation needs of the simulated fleet: a task worked landed (NAV_LAND, then
NAV_DELAY for its duration while staying armed, then a take-off - on PX4; ArduCopter disarms at the
landing and restarts its mission instead), a task worked hovering timed by NAV_LOITER_TIME, and a
battery swap on the deck (MAV_CMD_BATTERY_RESET)."""

from __future__ import annotations

import math
from collections.abc import AsyncIterator

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M
from sitl_helpers import Gcs, enu_to_latlon, make_config

from sitl import SimFleet

REL = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
PX4_MISSION = (1, 4, 4)
SPEEDUP = 5.0


def item(cmd: int, x: float = 0.0, y: float = 0.0, z: float = 0.0, p1: float = 0.0) -> tuple:
    lat, lon = enu_to_latlon(x, y)
    return (REL, cmd, p1, 0.0, 0.0, math.nan, lat, lon, z)


def delay(seconds: float) -> tuple:
    return (M.MAV_FRAME_MISSION, M.MAV_CMD_NAV_DELAY, seconds, -1.0, -1.0, -1.0, 0.0, 0.0, 0.0)


@pytest.fixture
async def fleet() -> AsyncIterator[SimFleet]:
    """The fleet at speed-up 5: the times below are read when the ground station gets a message, and
    a loaded machine's tens of wall ms are a second of simulated time at speed-up 20."""
    async with SimFleet(make_config(speedup=SPEEDUP)) as f:
        yield f
    assert f.errors == 0, f.last_error


async def reached_at(fleet: SimFleet, gcs: Gcs, seq: int, since: int) -> float:
    await gcs.recv("MISSION_ITEM_REACHED", sysid=11, since=since, timeout=10.0, where=lambda m: m.seq == seq)
    return fleet.sim_time


async def test_a_task_worked_landed_then_one_hovering_are_timed_by_the_firmware(fleet: SimFleet,
                                                                               gcs: Gcs) -> None:
    items = [item(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 1), item(M.MAV_CMD_NAV_WAYPOINT, 10, 0, 0.5),
             item(M.MAV_CMD_NAV_LAND, 10, 0, 0), delay(6.0), item(M.MAV_CMD_NAV_TAKEOFF, 10, 0, 1),
             item(M.MAV_CMD_NAV_WAYPOINT, 10, 10, 4), item(M.MAV_CMD_NAV_LOITER_TIME, 10, 10, 4, p1=5.0),
             item(M.MAV_CMD_NAV_LOITER_UNLIM, 10, 10, 4)]
    assert await gcs.upload(11, items) == M.MAV_MISSION_ACCEPTED
    assert (await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == M.MAV_RESULT_ACCEPTED
    since = gcs.mark()
    assert (await gcs.command(11, M.MAV_CMD_DO_SET_MODE, *PX4_MISSION)).result == M.MAV_RESULT_ACCEPTED
    rover, v = fleet.rover("r1"), fleet.vehicle("r1")
    landed = await reached_at(fleet, gcs, 2, since)
    assert rover.on_ground and not rover.loaded
    battery = rover.battery
    await fleet.wait_sim_time(landed + 3.0, timeout=5)
    assert rover.on_ground and v.armed and rover.battery == battery  # waiting landed burns nothing
    done = await reached_at(fleet, gcs, 3, since)
    assert done - landed == pytest.approx(6.0, abs=1.0)  # the NAV_DELAY (seen here: 0.2 s of wall time)
    arrived = await reached_at(fleet, gcs, 5, since)
    worked = await reached_at(fleet, gcs, 6, since)
    assert worked - arrived == pytest.approx(5.0, abs=1.0)  # the NAV_LOITER_TIME
    assert v.armed and rover.phase.value == "air" and v.current == 7  # waiting in the loiter


async def test_a_battery_swap_fills_a_disarmed_rover_on_the_deck_only(fleet: SimFleet, gcs: Gcs) -> None:
    rover, v = fleet.rover("r1"), fleet.vehicle("r1")
    rover.battery = 0.3
    ack = await gcs.command(11, M.MAV_CMD_BATTERY_RESET, 255, 100)
    assert ack.result == M.MAV_RESULT_ACCEPTED and rover.battery == 1.0
    assert (await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == M.MAV_RESULT_ACCEPTED
    rover.battery = 0.3
    assert (await gcs.command(11, M.MAV_CMD_BATTERY_RESET, 255, 100)).result == M.MAV_RESULT_DENIED
    assert rover.battery == 0.3 and v.armed


async def test_ardupilot_copter_disarms_at_a_missions_landing_and_restarts_it() -> None:
    """As ArduCopter 4.6 SITL does ("Disarming motors" after a mission's NAV_LAND, then "Mission: 1
    Takeoff"): the NAV_DELAY and the take-off after the landing never run, the vehicle stays
    disarmed on the ground, the mission's current item back at its first."""
    from sitl_helpers import open_gcs

    async with SimFleet(make_config(autopilot="ardupilot", speedup=SPEEDUP)) as fleet:
        gcs = await open_gcs(fleet.endpoints["carrier"])
        try:
            await gcs.recv("GLOBAL_POSITION_INT", sysid=11)
            home = item(M.MAV_CMD_NAV_WAYPOINT, 0, 0, 0)
            items = [home, item(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 1), item(M.MAV_CMD_NAV_WAYPOINT, 10, 0, 0.5),
                     item(M.MAV_CMD_NAV_LAND, 10, 0, 0), delay(2.0), item(M.MAV_CMD_NAV_TAKEOFF, 10, 0, 1),
                     item(M.MAV_CMD_NAV_WAYPOINT, 10, 10, 4)]
            assert await gcs.upload(11, items) == M.MAV_MISSION_ACCEPTED
            assert (await gcs.command(11, M.MAV_CMD_DO_SET_MODE, 1, 4)).result == M.MAV_RESULT_ACCEPTED
            assert (await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == M.MAV_RESULT_ACCEPTED
            assert (await gcs.command(11, M.MAV_CMD_MISSION_START, 0, 0)).result == M.MAV_RESULT_ACCEPTED
            rover, v = fleet.rover("r1"), fleet.vehicle("r1")
            await fleet.wait_for(lambda: rover.on_ground and not rover.loaded, 10)
            landed = fleet.sim_time
            await fleet.wait_for(lambda: not v.armed, 5)
            assert fleet.sim_time - landed <= fleet.vehicle("r1").flavour.disarm_delay() + 1.0
            await fleet.wait_sim_time(fleet.sim_time + 5.0, timeout=5)  # the NAV_DELAY would be over
            assert rover.on_ground and not v.armed and v.current == 1
            x, y, _z = rover.position
            assert math.hypot(x - 10, y) < 0.5  # it stayed at the task
        finally:
            gcs.close()
