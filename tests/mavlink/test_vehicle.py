"""fleetctl.mavlink.vehicle against the simulated fleet: state, commands, lost/back, compiled missions
with the carrier's hold at each stop and its release."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

import fleetctl.mavlink.vehicle as vehicle_module
from fleetctl.mavlink.compile import compile_for_fleet
from fleetctl.mavlink.fleet import Fleet, connect_fleet
from fleetctl.mavlink.vehicle import CommandRejected, VehicleEvent
from planners.core.plan import Plan, RoverLeg, Stop
from sitl import Fault, SimFleet
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet


async def test_state_from_telemetry(fleet: Fleet, sim: SimFleet) -> None:
    r1 = fleet.rovers["r1"]
    await r1.wait_until(lambda v: v.position is not None and v.landed_state is not None
                        and v.battery_pct is not None, 3.0, "telemetry")
    assert r1.autopilot is not None and r1.autopilot.name == "px4"
    assert r1.mode == "HOLD" and r1.mode_firmware == "AUTO.LOITER" and not r1.armed
    assert r1.landed_state_name == "ON_GROUND" and r1.on_ground
    assert r1.battery_pct == 100.0 and r1.battery_fraction == 1.0
    x, y, z = r1.enu
    assert math.dist((x, y, z), sim.rover("r1").position) < 0.05
    assert r1.last_heard_age is not None and r1.last_heard_age < 2.0
    assert fleet.carrier.autopilot.ground


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
async def test_arm_takeoff_goto_land(autopilot: str, tmp_path: Path) -> None:
    d = mission_dict(rovers=1)
    async with sim_fleet(d, autopilot=autopilot) as sim:
        async with await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0) as fleet:
            r1 = fleet.rovers["r1"]
            events = r1.event_queue()
            await r1.wait_until(lambda v: v.position is not None, 3.0, "position")
            await r1.arm()
            await r1.wait_until(lambda v: v.armed, 3.0, "armed")
            await r1.takeoff(6.0)
            await r1.wait_until(lambda v: v.relative_alt is not None and v.relative_alt > 5.9, 10.0, "6 m up")
            assert sim.rover("r1").position[2] == pytest.approx(6.0, abs=0.1)
            assert not sim.rover("r1").loaded
            await r1.goto_enu(15.0, -8.0, 4.0)
            await r1.wait_until(lambda v: math.dist(v.enu, (15.0, -8.0, 4.0)) < 0.1, 15.0, "goto target")
            assert math.dist(sim.rover("r1").position, (15.0, -8.0, 4.0)) < 0.1
            await r1.land()
            await r1.wait_until(lambda v: v.on_ground, 15.0, "landed")
            assert sim.rover("r1").on_ground and sim.rover("r1").position[2] == pytest.approx(0.0, abs=0.01)
            await r1.wait_until(lambda v: not v.armed, 10.0, "auto-disarm")
    kinds = []
    while not events.empty():
        ev: VehicleEvent = events.get_nowait()
        assert ev.vehicle == "r1" and ev.sysid == 11
        kinds.append(ev.kind)
    assert "armed" in kinds and "disarmed" in kinds and "landed_state" in kinds


async def test_refused_arm_says_why(tmp_path: Path) -> None:
    d = mission_dict(faults=[{"vehicle": "r2", "kind": "refuse_arm"}])
    async with sim_fleet(d) as sim:
        async with await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0) as fleet:
            with pytest.raises(CommandRejected, match="r2: MAV_CMD_COMPONENT_ARM_DISARM rejected "
                                                      r"\(MAV_RESULT_DENIED\): Arming denied") as exc:
                await fleet.rovers["r2"].arm()
            assert exc.value.ack.result_name == "MAV_RESULT_DENIED"
            await fleet.rovers["r1"].arm()
            assert sim.vehicle("r1").armed and not sim.vehicle("r2").armed


@pytest.mark.slow
async def test_lost_and_back(tmp_path: Path) -> None:
    d = mission_dict(heartbeat_timeout=2.0)  # the sim beats at 1 Hz
    async with sim_fleet(d) as sim:
        async with await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0) as fleet:
            q = fleet.event_queue()
            sim.dropout("r1", duration=3.5 * sim.speedup)  # 3.5 wall seconds of silence
            r1 = fleet.rovers["r1"]
            await r1.wait_until(lambda v: v.lost, 5.0, "lost")
            assert not fleet.rovers["r2"].lost and not fleet.carrier.lost
            await r1.wait_until(lambda v: not v.lost, 5.0, "back")
            seen = []
            while not q.empty():
                ev = q.get_nowait()
                if ev.kind in ("lost", "back"):
                    seen.append((ev.vehicle, ev.kind))
            assert seen == [("r1", "lost"), ("r1", "back")]


async def test_a_vehicle_heard_otherwise_is_not_lost_for_want_of_heartbeats(tmp_path: Path) -> None:
    """A lossy link drops heartbeats too: while any other message of the vehicle arrives (here: its
    link's last-heard time kept fresh while the simulator sends nothing), it is not lost; once
    nothing comes, it is lost after ``heartbeat_timeout``."""
    import asyncio
    import time

    d = mission_dict(heartbeat_timeout=1.0)
    async with sim_fleet(d) as sim:
        async with await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0) as fleet:
            r1 = fleet.rovers["r1"]
            sim.dropout("r1", duration=60.0 * sim.speedup)  # no heartbeat from now on

            async def other_messages(seconds: float) -> None:
                end = time.monotonic() + seconds
                while time.monotonic() < end:
                    r1.link.last_heard[r1.sysid] = time.monotonic()
                    await asyncio.sleep(0.1)

            await other_messages(3.0)  # three heartbeat timeouts without a heartbeat
            assert not r1.lost
            await r1.wait_until(lambda v: v.lost, 5.0, "lost")  # nothing heard at all


def two_stop_plan() -> Plan:
    s1 = Stop(position=(20.0, 0.0, 0.0), carrier_path=[(0.0, 0.0, 0.0), (10.0, 5.0, 0.0), (20.0, 0.0, 0.0)],
              rovers=[RoverLeg("r1", [(20.0, 0.0, 0.0), (26.0, 6.0, 5.0)], task="t1")])
    s2 = Stop(position=(40.0, 0.0, 0.0), carrier_path=[(20.0, 0.0, 0.0), (40.0, 0.0, 0.0)],
              rovers=[RoverLeg("r2", [(40.0, 0.0, 0.0), (44.0, -3.0, 2.0), (46.0, -6.0, 4.0)], task="t2")])
    return Plan("deploy", "manual", (0.0, 0.0, 0.0), 0.0, [s1, s2])


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
async def test_compiled_deployment_holds_the_carrier_until_released(autopilot: str, tmp_path: Path) -> None:
    d = mission_dict()
    async with sim_fleet(d, autopilot=autopilot) as sim:
        async with await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0) as fleet:
            compiled = compile_for_fleet(two_stop_plan(), fleet)
            carrier = fleet.carrier
            for vid, items in compiled.missions.items():
                await fleet.vehicles[vid].upload_mission(items)
            names = [i.name for i in await carrier.download_mission()]
            assert names[-2:] == ["NAV_WAYPOINT", "NAV_LOITER_UNLIM"]
            await carrier.arm()
            await carrier.start_mission()
            s0, s1 = compiled.stops
            await carrier.wait_item_reached(s0.arrive_seq, 20.0)
            await carrier.wait_until(lambda v: v.mission_current == s0.hold_seq, 5.0, "holding")
            assert math.dist(sim.body("carrier").position[:2], (20.0, 0.0)) < 0.2
            # launch the stop's rover from the deck while the carrier holds
            r1 = fleet.rovers["r1"]
            await r1.arm()
            await r1.start_mission()
            rm = compiled.rovers["r1"]
            await r1.wait_item_reached(rm.target_seq, 30.0)
            await r1.wait_until(lambda v: v.mission_current == rm.final_seq, 5.0, "loiter at task")
            assert math.dist(sim.rover("r1").position, (26.0, 6.0, 5.0)) < 0.2
            assert math.dist(sim.body("carrier").position[:2], (20.0, 0.0)) < 0.2  # still held
            assert carrier.mission_current == s0.hold_seq
            # release: on to stop 2; pause and continue on the way
            await carrier.set_current(s0.release_seq)
            await carrier.wait_until(lambda v: v.ground_speed and v.ground_speed > 1.0, 10.0, "moving")
            await carrier.pause()
            assert sim.vehicle("carrier").paused
            await carrier.resume()
            await carrier.wait_item_reached(s1.arrive_seq, 20.0)
            assert math.dist(sim.body("carrier").position[:2], (40.0, 0.0)) < 0.2
            assert s1.release_seq is None


async def test_collection_lands_rover_on_the_carrier(sim: SimFleet, fleet: Fleet) -> None:
    r1 = fleet.rovers["r1"]
    await r1.arm()
    await r1.takeoff(4.0)
    await r1.wait_until(lambda v: v.relative_alt > 3.9, 10.0, "airborne")
    await r1.goto_enu(8.0, 6.0, 4.0)
    await r1.wait_until(lambda v: math.dist(v.enu, (8.0, 6.0, 4.0)) < 0.1, 10.0, "away from the carrier")
    assert not sim.rover("r1").loaded
    stop = Stop(position=(0.0, 0.0, 0.0), carrier_path=[(0.0, 0.0, 0.0), (0.0, 0.0, 0.0)],
                rovers=[RoverLeg("r1", [(8.0, 6.0, 4.0), (0.0, 0.0, 0.0)])])
    compiled = compile_for_fleet(Plan("collect", "manual", (0.0, 0.0, 0.0), 0.0, [stop]), fleet)
    rm = compiled.rovers["r1"]
    assert [i.name for i in rm.items] == ["NAV_WAYPOINT", "NAV_LAND"]
    await r1.upload_mission(list(rm.items))
    await r1.start_mission()
    await r1.wait_until(lambda v: v.on_ground, 20.0, "landed")
    await sim.wait_for(lambda: sim.rover("r1").loaded, 5.0)


async def test_status_text_and_mission_events(sim: SimFleet, fleet: Fleet) -> None:
    sim.inject(Fault("latency", vehicle="r2", seconds=0.02))
    r2 = fleet.rovers["r2"]
    got: list[VehicleEvent] = []
    remove = r2.add_listener(got.append)
    await r2.arm()
    await r2.wait_until(lambda v: any(t == "Armed" for _, _, t in v.statustexts), 3.0, "status text")
    remove()
    assert any(e.kind == "statustext" and e.data["text"] == "Armed" for e in got)


class _Px4SetCurrentLink:
    """A link to one PX4 1.18 vehicle as it answers a release: MAV_CMD_DO_SET_MISSION_CURRENT is
    unsupported; MISSION_SET_CURRENT to an item the vehicle already stands on is reached at once and
    MISSION_CURRENT goes straight to the next item (the set item is never reported current)."""

    def __init__(self) -> None:
        from pymavlink.dialects.v20 import ardupilotmega as mav

        self.M = mav
        self.mav = mav.MAVLink(None, srcSystem=255, srcComponent=190)
        self.url = "fake://px4"
        self.last_heard: dict[int, float] = {}
        from fleetctl.mavlink.rtt import RoundTrip

        self.rtt = RoundTrip()  # no round trip measured: waits are the protocols' own timeouts
        self.handlers: list = []

    def subscribe(self, handler, *, sysid=None):  # type: ignore[no-untyped-def]
        self.handlers.append(handler)
        return lambda: None

    def feed(self, msg) -> None:  # type: ignore[no-untyped-def]
        for h in self.handlers:
            h(msg)

    async def command(self, sysid, command, params, **kw):  # type: ignore[no-untyped-def]
        from fleetctl.mavlink.link import CommandAck

        return CommandAck(sysid, command, self.M.MAV_RESULT_UNSUPPORTED, 1)

    def send(self, msg, sysid=None) -> None:  # type: ignore[no-untyped-def]
        import asyncio

        assert msg.get_type() == "MISSION_SET_CURRENT"
        loop = asyncio.get_running_loop()
        loop.call_soon(self.feed, self.M.MAVLink_mission_item_reached_message(msg.seq))
        loop.call_soon(self.feed, self.M.MAVLink_mission_current_message(msg.seq + 1, 4, 3, 1))


@pytest.mark.parametrize("reports_current", [False, True])
async def test_release_confirmed_when_px4_passes_the_item_at_once(reports_current: bool) -> None:
    from fleetctl.mavlink.vehicle import Vehicle

    link = _Px4SetCurrentLink()
    v = Vehicle(link, 1, name="carrier")  # type: ignore[arg-type]
    link.feed(link.M.MAVLink_mission_current_message(1, 4, 3, 1))  # holding on the loiter (item 1)
    if reports_current:  # the classic answer: item 2 current
        link.send = lambda msg, sysid=None: link.feed(  # type: ignore[method-assign]
            link.M.MAVLink_mission_current_message(msg.seq, 4, 3, 1))
    await v.set_current(2)
    assert v.mission_current == (2 if reports_current else 3)


class _CountingPx4Link(_Px4SetCurrentLink):
    """A PX4 that answers MISSION_SET_CURRENT with MISSION_CURRENT, and counts the commands it gets."""

    def __init__(self) -> None:
        super().__init__()
        self.commands: list[int] = []
        self.sent: list[str] = []
        self.reports = 0  # MISSION_CURRENT messages the vehicle got
        self.reports_when_sent: list[int] = []
        self.deaf_until_report = 0  # MISSION_SET_CURRENT ignored until this many MISSION_CURRENT reports

    def feed(self, msg) -> None:  # type: ignore[no-untyped-def]
        self.reports += msg.get_type() == "MISSION_CURRENT"
        super().feed(msg)

    async def command(self, sysid, command, params, **kw):  # type: ignore[no-untyped-def]
        from fleetctl.mavlink.link import CommandAck

        self.commands.append(command)
        if command in (self.M.MAV_CMD_DO_SET_MODE, self.M.MAV_CMD_COMPONENT_ARM_DISARM):
            return CommandAck(sysid, command, self.M.MAV_RESULT_ACCEPTED, 1)
        return await super().command(sysid, command, params, **kw)

    def send(self, msg, sysid=None) -> None:  # type: ignore[no-untyped-def]
        import asyncio

        self.sent.append(msg.get_type())
        self.reports_when_sent.append(self.reports)
        if self.reports < self.deaf_until_report:  # PX4 right after an upload: the message is ignored
            return
        loop = asyncio.get_running_loop()
        loop.call_soon(self.feed, self.M.MAVLink_mission_current_message(msg.seq, 4, 3, 1))


def _px4_vehicle(link: _CountingPx4Link):  # type: ignore[no-untyped-def]
    from fleetctl.mavlink.autopilots.px4 import Px4
    from fleetctl.mavlink.vehicle import Vehicle

    v = Vehicle(link, 11, name="r1")  # type: ignore[arg-type]
    v.autopilot = Px4(link.M.MAV_TYPE_QUADROTOR)
    return v


async def test_px4_current_item_set_by_message_without_asking_the_command_first() -> None:
    """PX4 refuses DO_SET_MISSION_CURRENT: the message goes out at once, no command round trip."""
    link = _CountingPx4Link()
    v = _px4_vehicle(link)
    link.feed(link.M.MAVLink_mission_current_message(1, 4, 3, 1))
    await v.set_current(2)
    assert v.mission_current == 2
    assert link.sent == ["MISSION_SET_CURRENT"]
    assert link.M.MAV_CMD_DO_SET_MISSION_CURRENT not in link.commands


async def test_started_mission_forgets_the_current_item_of_the_mission_before() -> None:
    """After the start the current item is unknown until the vehicle reports it: an index of the
    mission flown before (as a stock ArduPilot carrier reports until it takes the new mission) must
    not make a later item of the new one look passed."""
    link = _CountingPx4Link()
    v = _px4_vehicle(link)
    link.feed(link.M.MAVLink_mission_current_message(0, 4, 3, 1))
    link.feed(link.M.MAVLink_mission_current_message(5, 4, 3, 1))  # the old mission's index
    await v.start_mission(5)
    assert v.mission_current is None
    link.feed(link.M.MAVLink_mission_current_message(1, 4, 3, 1))
    assert v.mission_current == 1


async def test_px4_new_mission_starts_at_its_first_item_by_one_mode_switch(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A mission uploaded to a PX4 vehicle that had another current item gets item 0 current right
    after the upload. PX4 ignores MISSION_SET_CURRENT until its navigator took the new mission: the
    message is sent again on the next MISSION_CURRENT that does not show it (not after a 1.5 s
    silence). The start is then only the mode switch."""
    import asyncio

    link = _CountingPx4Link()
    v = _px4_vehicle(link)
    link.feed(link.M.MAVLink_mission_current_message(2, 4, 3, 1))  # the old mission's landing item
    assert v.autopilot is not None
    loop = asyncio.get_running_loop()
    link.deaf_until_report = 2  # deaf until the report that follows the upload
    monkeypatch.setattr(vehicle_module, "SET_CURRENT_RESEND", 3600.0)  # no resend by the clock
    loop.call_later(0.05, link.feed, link.M.MAVLink_mission_current_message(2, 3, 3, 1))  # index kept
    await v.autopilot.after_upload(v)
    assert v.mission_current == 0 and link.sent == ["MISSION_SET_CURRENT", "MISSION_SET_CURRENT"]
    assert link.reports_when_sent == [1, 2]  # sent at once, ignored, sent again after the next report
    await v.autopilot.after_upload(v)  # already at the first item: nothing sent
    assert link.sent == ["MISSION_SET_CURRENT", "MISSION_SET_CURRENT"]
    await v.start_mission()
    assert link.sent == ["MISSION_SET_CURRENT", "MISSION_SET_CURRENT"]
    assert link.commands == [link.M.MAV_CMD_DO_SET_MODE]


@pytest.mark.parametrize("mode", ["MISSION", "HOLD"])
async def test_a_px4_copter_left_in_mission_mode_is_armed_in_hold(mode: str) -> None:
    """PX4 flies the mission of a multicopter armed in mission mode at once: a rover armed ahead of
    its release on the ground is switched to HOLD first, so that its mission starts at the release."""
    link = _CountingPx4Link()
    v = _px4_vehicle(link)
    main = 4 << 16  # PX4 custom mode: AUTO, sub-mode MISSION (4) or LOITER (3)
    sub_mode = {"MISSION": 4, "HOLD": 3}[mode] << 24
    M = link.M
    link.feed(M.MAVLink_heartbeat_message(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4,
                                          M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main | sub_mode, 3, 3))
    assert v.mode == mode and not v.armed
    await v.arm()
    arm = link.M.MAV_CMD_COMPONENT_ARM_DISARM
    assert link.commands == ([link.M.MAV_CMD_DO_SET_MODE, arm] if mode == "MISSION" else [arm])


class _TakeoffPx4Link(_CountingPx4Link):
    """A PX4 that accepts NAV_TAKEOFF and keeps its parameters."""

    def __init__(self) -> None:
        super().__init__()
        self.params: list[tuple[float, ...]] = []

    async def command(self, sysid, command, params, **kw):  # type: ignore[no-untyped-def]
        from fleetctl.mavlink.link import CommandAck

        if command == self.M.MAV_CMD_NAV_TAKEOFF:
            self.commands.append(command)
            self.params.append(tuple(params))
            return CommandAck(sysid, command, self.M.MAV_RESULT_ACCEPTED, 1)
        return await super().command(sysid, command, params, **kw)


@pytest.mark.parametrize("landed", ["ON_GROUND", "IN_AIR"])
async def test_a_px4_copter_on_the_ground_takes_off_from_where_it_stands(landed: str) -> None:
    """PX4 takes off to an AMSL altitude and homes where it is armed: a rover standing 1 m above its
    last reported home (landed beside the deck; the new home arrives after the arm) climbs the
    height from where it stands; one in the air, from its home."""
    link = _TakeoffPx4Link()
    v = _px4_vehicle(link)
    M = link.M
    link.feed(M.MAVLink_home_position_message(473977420, 85455940, 487484, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0))
    link.feed(M.MAVLink_global_position_int_message(0, 473977420, 85455940, 488484, 1000, 0, 0, 0, 0))
    state = getattr(M, f"MAV_LANDED_STATE_{landed}")
    link.feed(M.MAVLink_extended_sys_state_message(M.MAV_VTOL_STATE_UNDEFINED, state))
    await v.takeoff(3.0)
    assert link.commands == [M.MAV_CMD_NAV_TAKEOFF]
    assert link.params[0][6] == pytest.approx(491.484 if landed == "ON_GROUND" else 490.484)
