"""ArduRover may set home from its barometer alone: HOME_POSITION near 0 m while GLOBAL_POSITION_INT
carries the true AMSL altitude, and relative_alt then reads that AMSL altitude. A ground vehicle is
then neither "airborne" nor 488 m up, and its home is where it stands."""

from __future__ import annotations

import asyncio
import socket

from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.link import Link
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.run.executor import is_airborne
from tests.run.ctl_helpers import free_udp_port

LAT, LON, AMSL = 47.397742, 8.545594, 488.0


async def _send(port: int, mav_type: int) -> None:
    mav = M.MAVLink(None, srcSystem=1, srcComponent=1)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for _ in range(10):
            msgs = [
                mav.heartbeat_encode(mav_type, M.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                     M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, M.MAV_STATE_STANDBY),
                mav.global_position_int_encode(1000, int(LAT * 1e7), int(LON * 1e7), int(AMSL * 1000),
                                               int(AMSL * 1000), 0, 0, 0, 0),
                mav.home_position_encode(int(LAT * 1e7), int(LON * 1e7), 500, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0),
            ]
            for m in msgs:
                s.sendto(m.pack(mav), ("127.0.0.1", port))
            await asyncio.sleep(0.05)


async def _vehicle(mav_type: int) -> tuple[float | None, float | None, bool]:
    port = free_udp_port()
    async with Link(f"udpin://127.0.0.1:{port}") as link:
        v = Vehicle(link, 1, name="carrier")
        await _send(port, mav_type)
        await v.wait_until(lambda v: v.home is not None and v.relative_alt is not None, 2.0, "telemetry")
        return v.height, v.home_amsl, is_airborne(v)


async def test_a_ground_vehicle_with_a_barometric_home_is_on_the_ground_at_its_own_altitude() -> None:
    height, home, airborne = await _vehicle(M.MAV_TYPE_GROUND_ROVER)
    assert height == 0.0 and not airborne
    assert home == AMSL


async def test_a_copter_keeps_its_reported_height_and_home() -> None:
    height, home, airborne = await _vehicle(M.MAV_TYPE_QUADROTOR)
    assert height == AMSL and airborne and home == 0.5
