"""MAVLink protocol of the simulated autopilots over real UDP: identity, mission transfer,
commands and their ACKs, parameters, system-id filtering."""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as M
from sitl_helpers import Gcs, enu_to_latlon

from sitl import Mode, SimFleet

REL = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def wp(x: float, y: float, z: float, hold: float = 0.0, cmd: int = M.MAV_CMD_NAV_WAYPOINT) -> tuple:
    lat, lon = enu_to_latlon(x, y)
    return (REL, cmd, hold, 0.0, 0.0, math.nan, lat, lon, z)


async def test_every_vehicle_on_the_shared_link_sends_heartbeats(fleet: SimFleet, gcs: Gcs) -> None:
    assert len(set(fleet.endpoints.values())) == 1  # rovers share the carrier's link
    carrier = await gcs.recv("HEARTBEAT", sysid=1)
    r1 = await gcs.recv("HEARTBEAT", sysid=11)
    r2 = await gcs.recv("HEARTBEAT", sysid=12)
    assert carrier.type == M.MAV_TYPE_GROUND_ROVER
    assert r1.type == r2.type == M.MAV_TYPE_QUADROTOR
    assert {carrier.autopilot, r1.autopilot} == {M.MAV_AUTOPILOT_PX4}
    assert r1.get_srcComponent() == 1
    for mtype in ("GLOBAL_POSITION_INT", "SYS_STATUS", "BATTERY_STATUS", "EXTENDED_SYS_STATE",
                  "HOME_POSITION", "MISSION_CURRENT"):
        await gcs.recv(mtype, sysid=11)
    pos = await gcs.recv("GLOBAL_POSITION_INT", sysid=12)
    assert (pos.lat, pos.lon) == (473977420, 85455940)  # loaded on the carrier at the origin


async def test_mission_upload_download_and_clear(fleet: SimFleet, gcs: Gcs) -> None:
    items = [wp(0, 0, 5, cmd=M.MAV_CMD_NAV_TAKEOFF), wp(10, 5, 5, hold=3.0), wp(0, 0, 5),
             wp(0, 0, 0, cmd=M.MAV_CMD_NAV_LAND)]
    assert await gcs.upload(11, items) == M.MAV_MISSION_ACCEPTED
    v = fleet.vehicle("r1")
    assert [i.command for i in v.mission] == [i[1] for i in items]
    assert fleet.vehicle("r2").mission == []  # only the addressed vehicle took it
    got = await gcs.download(11)
    assert [m.seq for m in got] == [0, 1, 2, 3]
    assert [m.command for m in got] == [i[1] for i in items]
    assert got[1].param1 == 3.0 and got[1].frame == REL
    assert got[1].x == round(items[1][6] * 1e7) and got[1].y == round(items[1][7] * 1e7)
    assert got[1].z == 5.0

    since = gcs.mark()
    gcs.send(gcs.mav.mission_clear_all_encode(11, 1, 0))
    ack = await gcs.recv("MISSION_ACK", sysid=11, since=since)
    assert ack.type == M.MAV_MISSION_ACCEPTED
    assert v.mission == []
    assert await gcs.download(11) == []


async def test_out_of_sequence_item_gets_invalid_sequence_and_keeps_the_old_mission(
        fleet: SimFleet, gcs: Gcs) -> None:
    assert await gcs.upload(11, [wp(1, 1, 3)]) == M.MAV_MISSION_ACCEPTED
    since = gcs.mark()
    gcs.send(gcs.mav.mission_count_encode(11, 1, 3, 0))
    req = await gcs.recv("MISSION_REQUEST_INT", sysid=11, since=since)
    assert req.seq == 0
    lat, lon = enu_to_latlon(5, 5)
    gcs.send(gcs.mav.mission_item_int_encode(11, 1, 2, REL, M.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, 0,
                                             int(lat * 1e7), int(lon * 1e7), 3.0, 0))
    ack = await gcs.recv("MISSION_ACK", sysid=11, since=since)
    assert ack.type == M.MAV_MISSION_INVALID_SEQUENCE
    assert len(fleet.vehicle("r1").mission) == 1


async def test_duplicate_item_is_answered_with_a_new_request(fleet: SimFleet, gcs: Gcs) -> None:
    since = gcs.mark()
    gcs.send(gcs.mav.mission_count_encode(11, 1, 2, 0))
    await gcs.recv("MISSION_REQUEST_INT", sysid=11, since=since, where=lambda m: m.seq == 0)
    item = wp(2, 2, 3)
    frame, cmd, p1, p2, p3, p4, lat, lon, alt = item
    for _ in range(2):  # item 0 twice
        gcs.send(gcs.mav.mission_item_int_encode(11, 1, 0, frame, cmd, 0, 1, p1, p2, p3, p4,
                                                 int(lat * 1e7), int(lon * 1e7), alt, 0))
    since2 = gcs.mark()
    await gcs.recv("MISSION_REQUEST_INT", sysid=11, since=since, where=lambda m: m.seq == 1)
    second = await gcs.recv("MISSION_REQUEST_INT", sysid=11, since=since2, where=lambda m: m.seq == 1)
    assert second.seq == 1
    gcs.send(gcs.mav.mission_item_int_encode(11, 1, 1, frame, cmd, 0, 1, p1, p2, p3, p4,
                                             int(lat * 1e7), int(lon * 1e7), alt, 0))
    ack = await gcs.recv("MISSION_ACK", sysid=11, since=since)
    assert ack.type == M.MAV_MISSION_ACCEPTED
    assert len(fleet.vehicle("r1").mission) == 2


async def test_vehicle_re_requests_a_missing_item_after_its_timeout(fleet: SimFleet, gcs: Gcs) -> None:
    since = gcs.mark()
    gcs.send(gcs.mav.mission_count_encode(11, 1, 1, 0))
    first = await gcs.recv("MISSION_REQUEST_INT", sysid=11, since=since)
    again = await gcs.recv("MISSION_REQUEST_INT", sysid=11, since=gcs.received.index(first) + 1, timeout=4.0)
    assert first.seq == again.seq == 0
    gcs.send(gcs.mav.mission_ack_encode(11, 1, M.MAV_MISSION_OPERATION_CANCELLED, 0))  # give up


async def test_unsupported_items_and_frames_are_rejected(fleet: SimFleet, gcs: Gcs) -> None:
    bad_cmd = (REL, M.MAV_CMD_DO_DIGICAM_CONTROL, 0, 0, 0, 0, 0.0, 0.0, 0.0)
    assert await gcs.upload(11, [bad_cmd]) == M.MAV_MISSION_UNSUPPORTED
    bad_frame = (M.MAV_FRAME_LOCAL_NED, M.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, 0.0, 0.0, 5.0)
    assert await gcs.upload(11, [wp(1, 1, 1), bad_frame]) == M.MAV_MISSION_UNSUPPORTED_FRAME
    assert fleet.vehicle("r1").mission == []


async def test_download_request_out_of_range(fleet: SimFleet, gcs: Gcs) -> None:
    since = gcs.mark()
    gcs.send(gcs.mav.mission_request_int_encode(11, 1, 5, 0))
    ack = await gcs.recv("MISSION_ACK", sysid=11, since=since)
    assert ack.type == M.MAV_MISSION_INVALID_SEQUENCE


async def test_commands_are_acknowledged(fleet: SimFleet, gcs: Gcs) -> None:
    ack = await gcs.command(11, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    assert ack.result == M.MAV_RESULT_DENIED  # disarmed
    assert ack.target_system == 255 and ack.target_component == 190
    ack = await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert ack.result == M.MAV_RESULT_ACCEPTED
    assert fleet.vehicle("r1").armed
    hb = await gcs.recv("HEARTBEAT", sysid=11, where=lambda m: m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
    assert hb.system_status == M.MAV_STATE_ACTIVE
    ack = await gcs.command(11, M.MAV_CMD_DO_DIGICAM_CONTROL)
    assert ack.result == M.MAV_RESULT_UNSUPPORTED
    ack = await gcs.command(11, M.MAV_CMD_DO_SET_MODE, 1, 4, 4)  # PX4 mission mode, no mission
    assert ack.result == M.MAV_RESULT_DENIED
    ack = await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    assert ack.result == M.MAV_RESULT_ACCEPTED and not fleet.vehicle("r1").armed
    ack = await gcs.command(1, M.MAV_CMD_NAV_TAKEOFF)
    assert ack.result == M.MAV_RESULT_UNSUPPORTED  # the carrier is a ground vehicle


async def test_set_mode_is_reported_in_the_heartbeat(fleet: SimFleet, gcs: Gcs) -> None:
    ack = await gcs.command(11, M.MAV_CMD_DO_SET_MODE, 1, 3, 0)  # PX4 POSCTL
    assert ack.result == M.MAV_RESULT_ACCEPTED
    assert fleet.vehicle("r1").mode is Mode.MANUAL
    await gcs.recv("HEARTBEAT", sysid=11, where=lambda m: m.custom_mode == 3 << 16)
    ack = await gcs.command(11, M.MAV_CMD_DO_SET_MODE, 1, 9, 0)
    assert ack.result == M.MAV_RESULT_DENIED


async def test_request_message_and_message_interval(fleet: SimFleet, gcs: Gcs) -> None:
    since = gcs.mark()
    ack = await gcs.command(11, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    assert ack.result == M.MAV_RESULT_ACCEPTED
    ver = await gcs.recv("AUTOPILOT_VERSION", sysid=11, since=since)
    assert ver.capabilities & M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    assert ver.capabilities & M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    ack = await gcs.command(11, M.MAV_CMD_REQUEST_MESSAGE, 9999)
    assert ack.result == M.MAV_RESULT_UNSUPPORTED

    since = gcs.mark()
    ack = await gcs.command(12, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE, 50_000)
    assert ack.result == M.MAV_RESULT_ACCEPTED
    await gcs.recv("ATTITUDE", sysid=12, since=since)
    await gcs.none("ATTITUDE", sysid=11, since=since, wait=0.3)

    ack = await gcs.command(12, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, -1)
    assert ack.result == M.MAV_RESULT_ACCEPTED
    await gcs.recv("GLOBAL_POSITION_INT", sysid=11, since=gcs.mark())  # others keep streaming
    await gcs.none("GLOBAL_POSITION_INT", sysid=12, since=gcs.mark(), wait=0.4)


async def test_messages_for_another_system_are_ignored(fleet: SimFleet, gcs: Gcs) -> None:
    since = gcs.mark()
    ack = await gcs.command(12, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert ack.get_srcSystem() == 12 and ack.result == M.MAV_RESULT_ACCEPTED
    assert fleet.vehicle("r2").armed and not fleet.vehicle("r1").armed and not fleet.vehicle("carrier").armed
    await gcs.none("COMMAND_ACK", since=since, wait=0.3, where=lambda m: m.get_srcSystem() != 12)

    since = gcs.mark()
    gcs.send(gcs.mav.command_long_encode(99, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))
    gcs.send(gcs.mav.mission_count_encode(99, 1, 2, 0))
    gcs.send(gcs.mav.command_long_encode(11, 42, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))
    await gcs.none("COMMAND_ACK", since=since, wait=0.4)
    await gcs.none("MISSION_REQUEST_INT", since=since, wait=0.1)
    assert not fleet.vehicle("r1").armed
    assert fleet.vehicle("r1").ignored_other_target >= 2


async def test_parameters(fleet: SimFleet, gcs: Gcs) -> None:
    since = gcs.mark()
    gcs.send(gcs.mav.param_set_encode(11, 1, b"MIS_TAKEOFF_ALT", 7.5, M.MAV_PARAM_TYPE_REAL32))
    pv = await gcs.recv("PARAM_VALUE", sysid=11, since=since)
    assert pv.param_id == "MIS_TAKEOFF_ALT" and pv.param_value == 7.5
    since = gcs.mark()
    gcs.send(gcs.mav.param_request_read_encode(11, 1, b"MIS_TAKEOFF_ALT", -1))
    pv = await gcs.recv("PARAM_VALUE", sysid=11, since=since)
    assert pv.param_value == 7.5
    since = gcs.mark()
    gcs.send(gcs.mav.param_request_list_encode(12, 1))
    first = await gcs.recv("PARAM_VALUE", sysid=12, since=since)
    names = {first.param_id}
    for _ in range(first.param_count - 1):
        m = await gcs.recv("PARAM_VALUE", sysid=12, since=gcs.received.index(first) + 1,
                           where=lambda m: m.param_id not in names)
        names.add(m.param_id)
    assert "MIS_TAKEOFF_ALT" in names and len(names) == first.param_count
    since = gcs.mark()
    gcs.send(gcs.mav.param_request_read_encode(11, 1, b"NO_SUCH_PARAM", -1))
    await gcs.none("PARAM_VALUE", sysid=11, since=since, wait=0.3)

    # the takeoff height parameter is used by a takeoff without an altitude (PX4: NaN)
    assert (await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == M.MAV_RESULT_ACCEPTED
    ack = await gcs.command(11, M.MAV_CMD_NAV_TAKEOFF, math.nan, 0, 0, math.nan, math.nan, math.nan, math.nan)
    assert ack.result == M.MAV_RESULT_ACCEPTED
    r1 = fleet.rover("r1")
    await fleet.wait_for(lambda: r1.arrived and not r1.on_ground, timeout=5)
    assert r1.position[2] == 7.5


async def test_ping_and_mission_set_current(fleet: SimFleet, gcs: Gcs) -> None:
    since = gcs.mark()
    gcs.send(gcs.mav.ping_encode(123456, 7, 0, 0))
    pongs = [await gcs.recv("PING", sysid=s, since=since) for s in (1, 11, 12)]
    assert all(p.seq == 7 and p.time_usec == 123456 and p.target_system == 255 for p in pongs)

    assert await gcs.upload(11, [wp(1, 1, 3), wp(2, 2, 3), wp(3, 3, 3)]) == M.MAV_MISSION_ACCEPTED
    since = gcs.mark()
    gcs.send(gcs.mav.mission_set_current_encode(11, 1, 2))
    cur = await gcs.recv("MISSION_CURRENT", sysid=11, since=since)
    assert cur.seq == 2 and cur.total == 3
    ack = await gcs.command(11, M.MAV_CMD_DO_SET_MISSION_CURRENT, 5)
    assert ack.result == M.MAV_RESULT_DENIED
    ack = await gcs.command(11, M.MAV_CMD_DO_SET_MISSION_CURRENT, 1)
    assert ack.result == M.MAV_RESULT_ACCEPTED and fleet.vehicle("r1").current == 1


def _per_second(gcs: Gcs, since: int, mtype: str, sysid: int, seconds: float) -> float:
    n = sum(1 for m in gcs.received[since:] if m.get_type() == mtype and m.get_srcSystem() == sysid)
    return n / seconds


async def test_streams_keep_their_rates_per_simulated_second(fleet: SimFleet, gcs: Gcs) -> None:
    """At speed-up 20 a rover's 1 Hz streams come about once per simulated second and its 10 Hz
    positions once per tick of the loop (2.5 per simulated second at 50 ticks per wall second), as
    a firmware in software-in-the-loop sends them: not once per wall second (0.05 per simulated
    second)."""
    since, t0 = gcs.mark(), fleet.sim_time
    await fleet.wait_sim_time(t0 + 20.0, timeout=10.0)
    span = fleet.sim_time - t0
    assert 0.5 <= _per_second(gcs, since, "HEARTBEAT", 11, span) <= 1.2
    assert 0.5 <= _per_second(gcs, since, "MISSION_CURRENT", 11, span) <= 1.2
    assert _per_second(gcs, since, "GLOBAL_POSITION_INT", 11, span) >= 1.0


async def test_a_slow_simulation_streams_at_least_per_wall_second() -> None:
    """Below real time (speed-up 0.25) the streams keep their rates per wall second: a ground
    station still hears a heartbeat every second."""
    import asyncio
    import time

    from sitl_helpers import make_config, open_gcs

    async with SimFleet(make_config(speedup=0.25)) as slow:
        g = await open_gcs(slow.endpoints["carrier"])
        try:
            await g.recv("HEARTBEAT", sysid=11)
            since, w0 = g.mark(), time.monotonic()
            await asyncio.sleep(3.0)
            assert _per_second(g, since, "HEARTBEAT", 11, time.monotonic() - w0) >= 0.6
        finally:
            g.close()


def test_the_documented_tick_rate() -> None:
    """docs/mavlink.md: the simulated fleet sends a stream at most once per tick of its loop."""
    from pathlib import Path

    from sitl import FleetConfig

    text = " ".join((Path(__file__).parents[2] / "docs" / "mavlink.md").read_text().split())
    tick = FleetConfig.__dataclass_fields__["tick_hz"].default
    assert f"(`tick_hz`, {tick:g} wall Hz)" in text
