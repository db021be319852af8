"""Conformance: plain pymavlink ``mavutil`` (blocking, so it runs in a thread) uploads and downloads
a mission (legacy float MISSION_ITEM and MISSION_ITEM_INT) and does a command round trip."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from sitl_helpers import enu_to_latlon, make_config, url_addr

from sitl import SimFleet

WAIT = 5.0


def mavutil_session(port: int) -> dict[str, Any]:
    from pymavlink import mavutil

    m = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=250, source_component=190,
                                   dialect="ardupilotmega")
    try:
        mav = mavutil.mavlink
        out: dict[str, Any] = {}
        m.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        hb = m.wait_heartbeat(timeout=WAIT)
        assert hb is not None, "no heartbeat"
        out["heartbeat"] = (hb.get_srcSystem(), hb.autopilot, hb.type)
        target = hb.get_srcSystem()

        # -- upload with the legacy float MISSION_ITEM, as mavwp-based tools still do
        points = [(3, 16, 0.0, *enu_to_latlon(5.0, 0.0), 4.0), (3, 16, 2.0, *enu_to_latlon(5.0, 5.0), 6.0),
                  (3, 21, 0.0, 0.0, 0.0, 0.0)]
        m.waypoint_count_send(len(points))
        sent = []
        while True:
            req = m.recv_match(type=["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"], blocking=True,
                               timeout=WAIT)
            assert req is not None, "upload stalled"
            if req.get_type() == "MISSION_ACK":
                out["upload_ack"] = req.type
                break
            frame, cmd, hold, lat, lon, alt = points[req.seq]
            m.mav.mission_item_send(target, 1, req.seq, frame, cmd, 0, 1, hold, 0, 0, 0, lat, lon, alt)
            sent.append(req.get_type())
        out["requests"] = sent

        # -- download both ways
        m.waypoint_request_list_send()
        count = m.recv_match(type="MISSION_COUNT", blocking=True, timeout=WAIT)
        assert count is not None
        out["count"] = count.count
        floats, ints = [], []
        for seq in range(count.count):
            m.waypoint_request_send(seq)
            floats.append(m.recv_match(type="MISSION_ITEM", blocking=True, timeout=WAIT))
            m.mav.mission_request_int_send(target, 1, seq)
            ints.append(m.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=WAIT))
        m.mav.mission_ack_send(target, 1, mav.MAV_MISSION_ACCEPTED)
        out["float_items"] = [(i.seq, i.command, i.x, i.y, i.z, i.param1) for i in floats]
        out["int_items"] = [(i.seq, i.command, i.x, i.y, i.z) for i in ints]

        # -- command round trip
        m.arducopter_arm()
        ack = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=WAIT)
        assert ack is not None
        out["arm_ack"] = (ack.command, ack.result)
        m.motors_armed_wait()  # blocks until a HEARTBEAT says armed
        out["armed"] = m.motors_armed()
        return out
    finally:
        m.close()


async def test_mavutil_mission_transfer_and_command(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MAVLINK20", "1")
    async with SimFleet(make_config(1, rover_connections=["sim"])) as fleet:
        _, port = url_addr(fleet.endpoints["r1"])
        out = await asyncio.wait_for(asyncio.to_thread(mavutil_session, port), timeout=30)
        assert out["heartbeat"] == (11, 12, 2)  # sysid, MAV_AUTOPILOT_PX4, MAV_TYPE_QUADROTOR
        assert out["upload_ack"] == 0  # MAV_MISSION_ACCEPTED
        assert out["requests"] == ["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_REQUEST"]
        v = fleet.vehicle("r1")
        assert [i.command for i in v.mission] == [16, 16, 21]
        assert out["count"] == 3
        lat, lon = enu_to_latlon(5.0, 5.0)
        seq, cmd, x, y, z, hold = out["float_items"][1]
        assert (seq, cmd, z, hold) == (1, 16, 6.0, 2.0)
        assert x == pytest.approx(lat, abs=1e-5) and y == pytest.approx(lon, abs=1e-5)
        seq, cmd, xi, yi, z = out["int_items"][1]
        assert (seq, cmd, z) == (1, 16, 6.0) and xi == pytest.approx(lat * 1e7, abs=30)
        assert out["arm_ack"] == (400, 0)  # COMPONENT_ARM_DISARM accepted
        assert out["armed"] and v.armed
        assert fleet.errors == 0
