"""Commands on a link that loses their answers (fleetctl.mavlink.effects): a command is done when a
report of the vehicle heard after it was sent shows its effect, even when every COMMAND_ACK is
lost; a battery request whose answer is lost is asked again; MISSION_SET_CURRENT is sent again
after the link's retransmission timeout."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink import vehicle as vehicle_module
from fleetctl.mavlink.effects import heartbeat_shows
from fleetctl.mavlink.fleet import Fleet, connect_fleet
from fleetctl.mavlink.link import Link
from sitl import SimFleet
from tests.mavlink.test_link import waypoints
from tests.mavlink.test_vehicle import _CountingPx4Link, _px4_vehicle
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet


@contextlib.contextmanager
def losing(link: Link, lost: Callable[[Any], bool]) -> Iterator[list[str]]:
    """``link`` loses every incoming message for which ``lost(msg)`` holds, before any waiter or
    subscriber sees it (a lossy radio that happens to drop exactly those); yields their types."""
    dropped: list[str] = []
    dispatch = link._dispatch

    def receive(msg: Any, addr: Any) -> None:
        if lost(msg):
            dropped.append(msg.get_type())
            return
        dispatch(msg, addr)

    link._dispatch = receive  # type: ignore[method-assign]
    try:
        yield dropped
    finally:
        link._dispatch = dispatch  # type: ignore[method-assign]


def acks_of(sysid: int) -> Callable[[Any], bool]:
    return lambda m: m.get_type() == "COMMAND_ACK" and m.get_srcSystem() == sysid


async def test_arm_land_and_disarm_done_by_the_heartbeat_when_every_ack_is_lost(fleet: Fleet) -> None:
    r1 = fleet.rovers["r1"]
    await r1.wait_until(lambda v: v.armed is False and v.mode is not None, 3.0, "telemetry")
    with losing(r1.link, acks_of(r1.sysid)) as dropped:
        await r1.arm()
        assert r1.armed and r1.confirmed_by_telemetry == 1
        ack = await r1.command(M.MAV_CMD_COMPONENT_ARM_DISARM, (1, 0))  # armed already: its HEARTBEAT
        assert ack.by_effect and ack.attempts == 0 and r1.confirmed_by_telemetry == 2
        await r1.land()
        assert r1.mode == "LAND" and r1.confirmed_by_telemetry == 3
        await r1.disarm()
        assert not r1.armed and r1.confirmed_by_telemetry == 4
    assert "COMMAND_ACK" in dropped  # the vehicle did answer; its answers were lost


async def test_a_refused_command_is_still_refused(fleet: Fleet, sim: SimFleet) -> None:
    """The effect never shows for a command the vehicle refuses: its ACK decides."""
    from fleetctl.mavlink.vehicle import CommandRejected
    from sitl.faults import Fault

    r1 = fleet.rovers["r1"]
    await r1.wait_until(lambda v: v.mode is not None, 3.0, "telemetry")
    sim.faults.add(Fault(kind="refuse_arm", vehicle="r1", at=0.0))
    with pytest.raises(CommandRejected):
        await r1.arm()
    assert not r1.armed and r1.confirmed_by_telemetry == 0


async def test_ardupilot_start_done_by_telemetry_when_every_ack_is_lost(tmp_path: Path) -> None:
    """ArduPilot's start is three commands (GUIDED to arm, DO_SET_MISSION_CURRENT, MISSION_START):
    each is done by its effect (HEARTBEAT mode and armed flag, MISSION_CURRENT) with no ACK."""
    d = mission_dict()
    async with sim_fleet(d, autopilot="ardupilot") as sim, \
            await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0) as fleet:
        r1 = fleet.rovers["r1"]
        await r1.wait_until(lambda v: v.mode is not None and v.mission_current is not None, 3.0, "telemetry")
        await r1.upload_mission(waypoints(4))
        with losing(r1.link, acks_of(r1.sysid)):
            await r1.arm()
            await r1.start_mission()
        assert r1.armed and r1.mode == "MISSION"
        assert r1.confirmed_by_telemetry >= 3


async def test_a_lost_battery_reading_is_asked_for_again(fleet: Fleet, sim: SimFleet) -> None:
    """The first two answers to the battery request are lost: the request is sent again (it used
    to wait its whole timeout and return the stale reading)."""
    r1 = fleet.rovers["r1"]
    await r1.wait_until(lambda v: v.battery_pct is not None, 3.0, "telemetry")
    await r1.configure_streams(battery_hz=0.02)  # no streamed reading during the test
    sim.rover("r1").battery = 0.42
    lost = 2

    def first_readings(m: Any) -> bool:
        nonlocal lost
        if m.get_type() == "BATTERY_STATUS" and m.get_srcSystem() == r1.sysid and lost > 0:
            lost -= 1
            return True
        return False

    with losing(r1.link, first_readings) as dropped:
        assert await r1.refresh_battery(timeout=5.0) == 42.0
    assert dropped == ["BATTERY_STATUS", "BATTERY_STATUS"]


async def test_mission_set_current_is_sent_again_after_the_retransmission_timeout(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The first MISSION_SET_CURRENT is lost and no MISSION_CURRENT report comes: once the link
    knows its round trip, the message is sent again after the retransmission timeout, not after
    SET_CURRENT_RESEND (made an hour here)."""
    link = _CountingPx4Link()
    v = _px4_vehicle(link)
    link.feed(link.M.MAVLink_mission_current_message(1, 4, 3, 1))
    link.rtt.add(0.002)
    monkeypatch.setattr(vehicle_module, "SET_CURRENT_RESEND", 3600.0)
    send = link.send
    sent = 0

    def lossy_send(msg: Any, sysid: int | None = None) -> None:
        nonlocal sent
        sent += 1
        if sent > 1:
            send(msg, sysid)
        else:
            link.sent.append(msg.get_type())  # sent, and lost on the way

    link.send = lossy_send  # type: ignore[method-assign]
    async with asyncio.timeout(5.0):
        await v.set_current(2)
    assert v.mission_current == 2 and link.sent == ["MISSION_SET_CURRENT", "MISSION_SET_CURRENT"]


def test_only_a_heartbeat_heard_after_the_command_shows_its_effect() -> None:
    """A vehicle armed by its last HEARTBEAT is not taken as armed by a command sent now until a
    HEARTBEAT heard after it says so."""
    v = SimpleNamespace(heartbeats=5, armed=True)
    armed = heartbeat_shows(v, lambda x: x.armed)  # type: ignore[arg-type]
    assert not armed(v)
    v.heartbeats = 6
    assert armed(v)
    v.armed = False
    assert not armed(v)


def test_the_numbers_docs_mavlink_states() -> None:
    from fleetctl.mavlink.mission_protocol import EARLY_RESENDS
    from fleetctl.mavlink.rtt import MIN_RTO
    from fleetctl.mavlink.vehicle import DEFAULT_POSITION_HZ, SET_CURRENT_PATIENCE, SET_CURRENT_RESEND

    text = " ".join((Path(__file__).parents[2] / "docs" / "mavlink.md").read_text().split())
    words = {8: "eight"}
    assert f"{words[EARLY_RESENDS]} times in a row at that wait" in text
    assert f"without one ({SET_CURRENT_RESEND:g} s before a round trip is known), for " \
           f"{SET_CURRENT_PATIENCE:g} s in all" in text
    assert f"{MIN_RTO:g} s to" in text
    assert (f"the floor, {MIN_RTO:g} wall s, sets it - at speed-up 10 that is {MIN_RTO * 10:g} "
            "mission s") in text
    assert f"positions at {DEFAULT_POSITION_HZ:g} Hz" in text
    assert "confirmed_by_telemetry" in text
