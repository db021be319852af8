"""Conformance: MAVSDK 4.x (a native binding of the MAVSDK C++ library, written by nobody here)
flies a simulated rover: discovery, telemetry, mission_raw upload/download, arm, takeoff,
mission to its end, landing."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from typing import Any

import pytest
from sitl_helpers import enu_to_latlon, make_config

from sitl import SimFleet

mavsdk = pytest.importorskip("mavsdk.asyncio")
from mavsdk.asyncio import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.asyncio.plugins.action import ActionAsync  # noqa: E402
from mavsdk.asyncio.plugins.mission_raw import MissionItem, MissionRawAsync  # noqa: E402
from mavsdk.asyncio.plugins.telemetry import FlightMode, LandedState, TelemetryAsync  # noqa: E402

pytestmark = pytest.mark.slow

REL_INT = 6  # MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
NAV_WAYPOINT = 16


async def first(gen: AsyncIterator[Any], where=lambda _: True, timeout: float = 10.0) -> Any:
    async def run() -> Any:
        async for x in gen:
            if where(x):
                return x
        raise AssertionError("stream ended")

    try:
        return await asyncio.wait_for(run(), timeout)
    finally:
        await gen.aclose()


async def eventually(check: Any, timeout: float = 5.0) -> bool:
    """Whether ``await check()`` comes true within ``timeout`` s (asked every 0.1 s)."""
    end = asyncio.get_running_loop().time() + timeout
    while not await check():
        if asyncio.get_running_loop().time() > end:
            return False
        await asyncio.sleep(0.1)
    return True


def waypoint(seq: int, x: float, y: float, z: float, frame: int = REL_INT) -> MissionItem:
    lat, lon = enu_to_latlon(x, y)
    return MissionItem(seq=seq, frame=frame, command=NAV_WAYPOINT, current=1 if seq == 0 else 0,
                       autocontinue=1, param1=0.0, param2=0.5, param3=0.0, param4=float("nan"),
                       x=int(round(lat * 1e7)), y=int(round(lon * 1e7)), z=z, mission_type=0)


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
async def test_mavsdk_flies_a_simulated_rover(autopilot: str) -> None:
    cfg = make_config(1, speedup=10.0, rover_connections=["sim"], autopilot=autopilot)
    async with SimFleet(cfg) as fleet:
        url = fleet.endpoints["r1"].replace("udp://", "udpout://")  # MAVSDK: udpout = we send there
        conf = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
        async with Mavsdk(conf) as sdk:
            await sdk.add_any_connection(url)
            system = await sdk.first_autopilot(timeout_s=10.0)
            assert system is not None and await system.get_system_id() == 11
            tel, action, mission = TelemetryAsync(system), ActionAsync(system), MissionRawAsync(system)
            for set_rate in (tel.set_rate_position, tel.set_rate_battery, tel.set_rate_landed_state):
                await asyncio.wait_for(set_rate(10.0), 10)  # SET_MESSAGE_INTERVAL, must be ACKed

            pos = await first(tel.subscribe_position())
            assert pos.latitude_deg == pytest.approx(47.397742, abs=1e-6)
            assert pos.relative_altitude_m == pytest.approx(0.0, abs=0.01)
            bat = await first(tel.subscribe_battery())
            assert bat.remaining_percent == pytest.approx(100.0)
            assert await first(tel.subscribe_landed_state()) == LandedState.ON_GROUND
            assert await first(tel.subscribe_flight_mode()) == FlightMode.HOLD

            points = [(10, 0, 5, REL_INT), (10, 10, 5, REL_INT), (0, 0, 5, REL_INT)]
            if autopilot == "ardupilot":
                points.insert(0, (0, 0, 488.0, 0))  # ArduPilot: item 0 is home (MAV_FRAME_GLOBAL)
            items = [waypoint(seq, *p) for seq, p in enumerate(points)]
            await asyncio.wait_for(mission.upload_mission(items), 10)
            down = await asyncio.wait_for(mission.download_mission(), 10)
            assert [(i.seq, i.command, i.frame, i.x, i.y, i.z) for i in down] == [
                (i.seq, i.command, i.frame, i.x, i.y, i.z) for i in items]

            await asyncio.wait_for(action.arm(), 10)
            assert await first(tel.subscribe_armed(), where=bool)
            await asyncio.wait_for(action.set_takeoff_altitude(5.0), 10)
            await asyncio.wait_for(action.takeoff(), 10)
            up = await first(tel.subscribe_position(), where=lambda p: p.relative_altitude_m > 4.5)
            assert up.relative_altitude_m == pytest.approx(5.0, abs=0.5)
            assert await first(tel.subscribe_landed_state(), where=lambda s: s == LandedState.IN_AIR)
            assert not fleet.rover("r1").loaded

            progress = mission.subscribe_mission_progress()
            await asyncio.wait_for(mission.start_mission(), 10)
            assert await first(tel.subscribe_flight_mode(), where=lambda m: m == FlightMode.MISSION)
            n = len(items)
            done = await first(progress, where=lambda p: p.total == n and p.current == n, timeout=20)
            assert done.current == done.total == n
            # (in CI the finished state once read False right after the progress showed the last
            # item: likely the MISSION_CURRENT after MISSION_ITEM_REACHED, handled a moment later)
            assert await eventually(lambda: asyncio.wait_for(mission.is_mission_finished(), 10))
            assert fleet.rover("r1").position == pytest.approx((0.0, 0.0, 5.0), abs=0.02)

            await asyncio.wait_for(action.land(), 10)
            await first(tel.subscribe_landed_state(), where=lambda s: s == LandedState.ON_GROUND, timeout=20)
            await first(tel.subscribe_armed(), where=lambda a: not a, timeout=20)  # auto-disarm
            assert fleet.rover("r1").loaded  # landed back on the (stopped) carrier
            assert fleet.errors == 0
