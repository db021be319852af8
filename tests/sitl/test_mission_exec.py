"""Mission execution and flight commands, observed over MAVLink and in the world state."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M
from sitl_helpers import ORIGIN, Gcs, enu_to_latlon, make_config, open_gcs

from sitl import Mode, SimFleet

REL = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
TOL = 0.02  # m: MAVLink positions carry 1e-7 degrees
PX4_MISSION = (1, 4, 4)  # DO_SET_MODE params: base mode, PX4 AUTO, MISSION


def item(cmd: int, x: float = 0.0, y: float = 0.0, z: float = 0.0, p1: float = 0.0, p2: float = 0.0,
         frame: int = REL) -> tuple:
    lat, lon = enu_to_latlon(x, y)
    return (frame, cmd, p1, p2, 0.0, math.nan, lat, lon, z)


def wp(x: float, y: float, z: float, hold: float = 0.0) -> tuple:
    return item(M.MAV_CMD_NAV_WAYPOINT, x, y, z, p1=hold)


async def reached(gcs: Gcs, sysid: int, seq: int, since: int, timeout: float = 10.0):
    return await gcs.recv("MISSION_ITEM_REACHED", sysid=sysid, since=since, timeout=timeout,
                          where=lambda m: m.seq == seq)


async def test_rover_flies_a_mission_and_lands_back_on_the_carrier(fleet: SimFleet, gcs: Gcs) -> None:
    items = [item(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 5), wp(20, 0, 5, hold=2.0), wp(0, 0, 5),
             item(M.MAV_CMD_NAV_LAND, 0, 0, 0)]
    assert await gcs.upload(11, items) == M.MAV_MISSION_ACCEPTED
    assert (await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == M.MAV_RESULT_ACCEPTED
    since = gcs.mark()
    assert (await gcs.command(11, M.MAV_CMD_DO_SET_MODE, *PX4_MISSION)).result == M.MAV_RESULT_ACCEPTED
    rover = fleet.rover("r1")
    await fleet.wait_for(lambda: not rover.loaded, timeout=3)
    marks = []
    for seq in range(4):
        m = await reached(gcs, 11, seq, since)
        marks.append(gcs.received.index(m))
        if seq == 1:
            # 1 s climb + 4 s to the waypoint + 2 s hold: not reported before it was held
            assert fleet.sim_time >= 7.0 - 1e-6
    assert marks == sorted(marks)
    currents = [m.seq for m in gcs.received[since:]
                if m.get_type() == "MISSION_CURRENT" and m.get_srcSystem() == 11]
    assert currents[-1] == 3 and currents == sorted(currents)
    await gcs.recv("MISSION_CURRENT", sysid=11, since=since, where=lambda m: m.mission_state == 5)  # COMPLETE
    v = fleet.vehicle("r1")
    assert v.finished
    assert rover.loaded and rover.on_ground
    # 12 s in the air (1 s up, 4 s out, 2 s hold, 4 s back, 1 s down) at 5 m/s on 200 m: hovering
    # costs as much as flying
    assert rover.battery == pytest.approx(1.0 - 12.0 * 5.0 / 200.0, abs=0.01)
    await fleet.wait_for(lambda: not v.armed, timeout=3)  # auto-disarm after landing
    assert any("Landed on carrier" in text for _, _, text in v.statustexts)
    ext = await gcs.recv("EXTENDED_SYS_STATE", sysid=11, since=gcs.mark())
    assert ext.landed_state == M.MAV_LANDED_STATE_ON_GROUND


async def test_carrier_holds_at_a_stop_until_released(fleet: SimFleet, gcs: Gcs) -> None:
    assert await gcs.upload(1, [wp(30, 0, 0, hold=1000.0), wp(30, 30, 0)]) == M.MAV_MISSION_ACCEPTED
    assert (await gcs.command(1, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == M.MAV_RESULT_ACCEPTED
    since = gcs.mark()
    assert (await gcs.command(1, M.MAV_CMD_MISSION_START)).result == M.MAV_RESULT_ACCEPTED
    carrier = fleet.body("carrier")
    await fleet.wait_for(lambda: carrier.arrived and carrier.position[0] > 29.0, timeout=5)
    assert carrier.position == pytest.approx((30.0, 0.0, 0.0), abs=TOL)
    assert fleet.rover("r1").position == pytest.approx((30.0, 0.0, 0.0), abs=TOL)  # loaded rovers ride along
    held = carrier.position
    await fleet.wait_sim_time(fleet.sim_time + 10.0, timeout=5)
    assert carrier.position == held and fleet.vehicle("carrier").current == 0
    await gcs.none("MISSION_ITEM_REACHED", sysid=1, since=since, wait=0.05)
    assert (await gcs.command(1, M.MAV_CMD_DO_SET_MISSION_CURRENT, 1)).result == M.MAV_RESULT_ACCEPTED
    await reached(gcs, 1, 1, since)
    assert carrier.position == pytest.approx((30.0, 30.0, 0.0), abs=TOL)
    assert fleet.rover("r2").position == pytest.approx((30.0, 30.0, 0.0), abs=TOL)
    assert fleet.vehicle("carrier").finished


async def test_loiter_unlimited_until_set_current(fleet: SimFleet, gcs: Gcs) -> None:
    items = [item(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 3), item(M.MAV_CMD_NAV_LOITER_UNLIM, 5, 5, 3), wp(0, 5, 3)]
    assert await gcs.upload(12, items) == M.MAV_MISSION_ACCEPTED
    await gcs.command(12, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    since = gcs.mark()
    await gcs.command(12, M.MAV_CMD_MISSION_START)
    rover = fleet.rover("r2")
    await fleet.wait_for(lambda: rover.arrived and rover.position[0] > 4.9, timeout=5)
    await fleet.wait_sim_time(fleet.sim_time + 20.0, timeout=5)
    assert fleet.vehicle("r2").current == 1 and rover.position == pytest.approx((5.0, 5.0, 3.0), abs=TOL)
    gcs.send(gcs.mav.mission_set_current_encode(12, 1, 2))
    await reached(gcs, 12, 2, since)
    assert rover.position == pytest.approx((0.0, 5.0, 3.0), abs=TOL)
    await gcs.none("MISSION_ITEM_REACHED", sysid=12, since=since, wait=0.01, where=lambda m: m.seq == 1)


async def test_pause_and_continue(fleet: SimFleet, gcs: Gcs) -> None:
    assert await gcs.upload(1, [wp(200, 0, 0)]) == M.MAV_MISSION_ACCEPTED
    await gcs.command(1, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    since = gcs.mark()
    await gcs.command(1, M.MAV_CMD_MISSION_START)
    carrier = fleet.body("carrier")
    await fleet.wait_for(lambda: carrier.position[0] > 20.0, timeout=5)
    assert (await gcs.command(1, M.MAV_CMD_DO_PAUSE_CONTINUE, 0)).result == M.MAV_RESULT_ACCEPTED
    await fleet.wait_for(lambda: carrier.speed == 0.0, timeout=5)
    x = carrier.position[0]
    await fleet.wait_sim_time(fleet.sim_time + 5.0, timeout=5)
    assert carrier.position[0] == x < 200.0
    cur = await gcs.recv("MISSION_CURRENT", sysid=1, since=gcs.mark())
    assert cur.mission_state == 4  # MISSION_STATE_PAUSED
    assert (await gcs.command(1, M.MAV_CMD_DO_PAUSE_CONTINUE, 1)).result == M.MAV_RESULT_ACCEPTED
    await reached(gcs, 1, 0, since)
    assert carrier.position == pytest.approx((200.0, 0.0, 0.0), abs=TOL)


async def test_change_speed_and_absolute_altitude_frame(fleet: SimFleet, gcs: Gcs) -> None:
    items = [item(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 2), item(M.MAV_CMD_DO_CHANGE_SPEED, p2=2.0, frame=2),
             item(M.MAV_CMD_NAV_WAYPOINT, 4, 0, ORIGIN[2] + 7.0, frame=M.MAV_FRAME_GLOBAL_INT)]
    assert await gcs.upload(11, items) == M.MAV_MISSION_ACCEPTED
    await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    since = gcs.mark()
    await gcs.command(11, M.MAV_CMD_MISSION_START)
    await reached(gcs, 11, 1, since)
    rover = fleet.rover("r1")
    assert rover.cruise_speed == 2.0
    await fleet.wait_for(lambda: rover.speed > 0, timeout=5)
    assert rover.speed <= 2.0 + 1e-9
    await reached(gcs, 11, 2, since)
    assert rover.position == pytest.approx((4.0, 0.0, 7.0), abs=TOL)


async def test_takeoff_reposition_and_return_to_launch(fleet: SimFleet, gcs: Gcs) -> None:
    await gcs.command(12, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    ack = await gcs.command(12, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, ORIGIN[2] + 4.0)
    assert ack.result == M.MAV_RESULT_ACCEPTED  # PX4: param7 is AMSL
    rover, v = fleet.rover("r2"), fleet.vehicle("r2")
    await fleet.wait_for(lambda: v.mode is Mode.HOLD and rover.position[2] > 3.9, timeout=5)
    assert rover.position == pytest.approx((0.0, 0.0, 4.0), abs=TOL)
    lat, lon = enu_to_latlon(8.0, -6.0)
    ack = await gcs.command_int(12, M.MAV_CMD_DO_REPOSITION, M.MAV_FRAME_GLOBAL_INT, (-1, 1, 0, math.nan),
                                lat, lon, ORIGIN[2] + 6.0)  # PX4: the altitude is AMSL
    assert ack.result == M.MAV_RESULT_ACCEPTED
    await fleet.wait_for(lambda: rover.arrived and rover.position[2] > 5.9, timeout=5)
    assert rover.position == pytest.approx((8.0, -6.0, 6.0), abs=TOL)
    assert (await gcs.command(12, M.MAV_CMD_NAV_RETURN_TO_LAUNCH)).result == M.MAV_RESULT_ACCEPTED
    await fleet.wait_for(lambda: rover.loaded, timeout=5)
    await fleet.wait_for(lambda: not v.armed, timeout=5)
    hb = await gcs.recv("HEARTBEAT", sysid=12, since=gcs.mark())
    assert hb.custom_mode == (4 << 16 | 5 << 24)  # PX4 AUTO.RTL


async def test_px4_takes_a_reposition_altitude_as_amsl_whatever_the_frame(fleet: SimFleet, gcs: Gcs) -> None:
    """As PX4 1.18 does: a DO_REPOSITION to 3 m in MAV_FRAME_GLOBAL_RELATIVE_ALT_INT is flown to 3 m
    AMSL - far below home: the rover comes down to the ground."""
    await gcs.command(12, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    await gcs.command(12, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, ORIGIN[2] + 4.0)
    rover = fleet.rover("r2")
    await fleet.wait_for(lambda: rover.position[2] > 3.9, timeout=5)
    lat, lon = enu_to_latlon(2.0, 0.0)
    ack = await gcs.command_int(12, M.MAV_CMD_DO_REPOSITION, REL, (-1, 1, 0, math.nan), lat, lon, 3.0)
    assert ack.result == M.MAV_RESULT_ACCEPTED
    await fleet.wait_for(lambda: rover.position[2] < 0.05, timeout=10)


async def test_land_command_away_from_the_carrier_stays_on_the_ground(fleet: SimFleet, gcs: Gcs) -> None:
    await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    await gcs.command(11, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, ORIGIN[2] + 3.0)
    rover = fleet.rover("r1")
    await fleet.wait_for(lambda: rover.position[2] > 2.9, timeout=5)
    lat, lon = enu_to_latlon(6.0, 0.0)
    ack = await gcs.command(11, M.MAV_CMD_NAV_LAND, 0, 0, 0, math.nan, lat, lon, 0)
    assert ack.result == M.MAV_RESULT_ACCEPTED
    await fleet.wait_for(lambda: rover.on_ground, timeout=5)
    # COMMAND_LONG carries lat/lon as float32: about half a metre of resolution
    assert not rover.loaded and rover.position == pytest.approx((6.0, 0.0, 0.0), abs=0.5)
    ack = await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    assert ack.result == M.MAV_RESULT_ACCEPTED


async def test_ardupilot_flavour() -> None:
    async with SimFleet(make_config(1, autopilot="ardupilot")) as fleet:
        gcs = await open_gcs(fleet.endpoints["r1"])
        try:
            hb = await gcs.recv("HEARTBEAT", sysid=11)
            assert hb.autopilot == M.MAV_AUTOPILOT_ARDUPILOTMEGA
            items = [wp(0, 0, 0), item(M.MAV_CMD_NAV_TAKEOFF, z=5), wp(10, 0, 5), item(M.MAV_CMD_NAV_LAND)]
            assert await gcs.upload(11, items) == M.MAV_MISSION_ACCEPTED
            got = await gcs.download(11)
            assert len(got) == 4 and got[0].frame == M.MAV_FRAME_GLOBAL  # item 0 = home
            assert (got[0].x, got[0].y) == (473977420, 85455940)
            cur = await gcs.recv("MISSION_CURRENT", sysid=11, since=gcs.mark())
            assert cur.seq == 1 and cur.total == 3
            ack = await gcs.command(11, M.MAV_CMD_DO_SET_MODE, 1, 4)  # GUIDED
            assert ack.result == M.MAV_RESULT_ACCEPTED
            assert fleet.vehicle("r1").mode is Mode.GUIDED
            await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            since = gcs.mark()
            ack = await gcs.command(11, M.MAV_CMD_DO_SET_MODE, 1, 3)  # AUTO
            assert ack.result == M.MAV_RESULT_ACCEPTED
            assert (await gcs.command(11, M.MAV_CMD_MISSION_START)).result == M.MAV_RESULT_ACCEPTED
            for seq in (1, 2, 3):
                await reached(gcs, 11, seq, since)
            await gcs.none("MISSION_ITEM_REACHED", sysid=11, since=since, wait=0.01,
                           where=lambda m: m.seq == 0)
            assert fleet.rover("r1").loaded
            hb = await gcs.recv("HEARTBEAT", sysid=11, since=since)
            assert hb.custom_mode == 3  # ArduCopter AUTO
            assert fleet.errors == 0
        finally:
            gcs.close()
