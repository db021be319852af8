"""Link-loss failsafe and geofence (docs/field-safety.md): parameters read, described and set
for PX4 and ArduPilot, the simulated autopilot acting on link loss and on a breach, the FENCE
mission round trip and plans checked against the fence. Real MAVLink over UDP."""

from __future__ import annotations

import asyncio
import json
import math
from pathlib import Path
from typing import Any

import pytest
from shapely.geometry import LineString, box
from shapely.ops import unary_union

from fleetctl.mavlink.fence import FENCE
from fleetctl.mavlink.fleet import connect_fleet
from fleetctl.mavlink.params import decode, encode, read_param, set_param
from fleetctl.mavlink.vehicle import Vehicle, VehicleEvent
from fleetctl.mission.model import GeofenceConfig
from fleetctl.run.context import ExecutionError
from fleetctl.run.flight import execute
from fleetctl.run.safety import (
    check_plan,
    download_fence,
    fence_items,
    line_clear,
    plan_violations,
    read_failsafe,
    set_failsafe,
    upload_fence,
)
from fleetctl.run.sim import sim_mission_dict
from planners.core.plan import Plan, RoverLeg, Stop
from sitl import FleetConfig, SimFleet
from sitl.flavour import Mode
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet

SQUARE = ((-20.0, -30.0), (70.0, -30.0), (70.0, 40.0), (-20.0, 40.0))


def test_px4_integer_parameters_travel_bytewise() -> None:
    from pymavlink.dialects.v20 import ardupilotmega as m

    f = encode(3, m.MAV_PARAM_TYPE_INT32, True)
    assert f != 3.0 and decode(f, m.MAV_PARAM_TYPE_INT32, True) == 3.0
    assert encode(3, m.MAV_PARAM_TYPE_INT32, False) == 3.0  # ArduPilot casts
    assert decode(2.5, m.MAV_PARAM_TYPE_REAL32, True) == 2.5


@pytest.mark.parametrize(
    ("autopilot", "rover", "carrier"),
    [
        (
            "px4",
            ("link loss: none (NAV_DLL_ACT 0)", "link loss: RTL after 10 s", {"NAV_DLL_ACT": 2.0}),
            ("link loss: none (NAV_DLL_ACT 0)", "link loss: hold after 10 s", {"NAV_DLL_ACT": 1.0}),
        ),
        (
            "ardupilot",
            ("link loss: none (FS_GCS_ENABLE 0)", "link loss: RTL after 5 s", {"FS_GCS_ENABLE": 1.0}),
            (
                "link loss: none (FS_GCS_ENABLE 0)",
                "link loss: hold after 1.5 s",
                {"FS_GCS_ENABLE": 1.0, "FS_ACTION": 2.0},
            ),
        ),
    ],
)
async def test_failsafe_read_described_and_set(
    autopilot: str, rover: tuple[Any, ...], carrier: tuple[Any, ...], tmp_path: Path
) -> None:
    d = mission_dict(rovers=1)
    async with sim_fleet(d, autopilot=autopilot) as sim:
        async with await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0) as fleet:
            for v, (before, after, params), action in (
                (fleet.rovers["r1"], rover, "rtl"),
                (fleet.carrier, carrier, "hold"),
            ):
                fs = await read_failsafe(v)
                assert fs.text == before and fs.action == "none"
                fs = await set_failsafe(v, action, fs)
                assert fs.text == after
                sim_params = sim.vehicle(v.name).flavour.params
                assert {k: sim_params[k] for k in params} == params
            assert await read_param(fleet.rovers["r1"], "NO_SUCH_PARAM", timeout=0.2, retries=1) is None


def test_ardupilot_failsafe_meanings() -> None:
    from pymavlink.dialects.v20 import ardupilotmega as m

    from fleetctl.mavlink.autopilots import ArduPilot, Px4

    copter = ArduPilot(m.MAV_TYPE_QUADROTOR)
    assert copter.describe_failsafe({"FS_GCS_ENABLE": 5, "FS_GCS_TIMEOUT": 3}) == "link loss: land after 3 s"
    assert copter.describe_failsafe({"FS_GCS_ENABLE": 1, "FS_GCS_TIMEOUT": 5, "FS_OPTIONS": 2}) == (
        "link loss: continue mission in AUTO, else RTL after 5 s"
    )
    assert copter.failsafe_params("hold", {"FS_OPTIONS": 18}) == {"FS_GCS_ENABLE": 7.0, "FS_OPTIONS": 16.0}
    assert copter.failsafe_params("land", {"FS_OPTIONS": 0}) == {"FS_GCS_ENABLE": 5.0}
    assert copter.fence_params(30, "hold") == {
        "FENCE_ENABLE": 1.0,
        "FENCE_ACTION": 4.0,
        "FENCE_TYPE": 5.0,
        "FENCE_ALT_MAX": 30.0,
    }
    px4 = Px4(m.MAV_TYPE_QUADROTOR)
    assert px4.describe_failsafe({"NAV_DLL_ACT": 3, "COM_DL_LOSS_T": 10}) == "link loss: land after 10 s"
    assert px4.describe_failsafe({"NAV_DLL_ACT": 6}) == "link loss: lockdown (motors off) after ?"
    assert px4.fence_params(None, "land") == {"GF_ACTION": 5.0, "GF_MAX_VER_DIST": 0.0}


@pytest.mark.parametrize(
    ("autopilot", "action", "param", "value"),
    [("px4", "land", "NAV_DLL_ACT", 3.0), ("ardupilot", "rtl", "FS_GCS_ENABLE", 1.0)],
)
async def test_links_failsafe_is_set_before_arming(
    autopilot: str, action: str, param: str, value: float, tmp_path: Path
) -> None:
    d = mission_dict(rovers=2)
    d["links"]["failsafe"] = action
    mission = mission_from(d, tmp_path)
    cfg = FleetConfig.from_mission_dict(sim_mission_dict(mission), speedup=20.0, autopilot=autopilot)
    async with SimFleet(cfg) as sim:
        out = await asyncio.wait_for(execute(mission, "deploy", sim=sim, runs_dir=tmp_path / "runs"), 120)
        values = {vid: sim.vehicle(vid).flavour.params[param] for vid in ("r1", "r2")}
    assert out.exit_code == 0, out.error
    assert values == {"r1": value, "r2": value}
    records = [json.loads(line) for line in (out.run_dir / "journal.jsonl").read_text().splitlines()]
    kinds = {r["kind"]: r for r in records}
    assert {r.get("vehicle") for r in records if r["kind"] == "failsafe_set"} == {"carrier", "r1", "r2"}
    warned = {r.get("vehicle") for r in records if r["kind"] == "failsafe_warning"}
    assert warned == ({"r1", "r2"} if action == "rtl" else set())
    assert "preflight_failed" not in kinds


async def _airborne(v: Vehicle, x: float = 15.0, y: float = -8.0, z: float = 6.0) -> None:
    await v.wait_until(lambda v: v.position is not None and v.home is not None, 3.0, "position")
    await v.arm()
    await v.wait_until(lambda v: v.armed, 3.0, "armed")
    await v.takeoff(z)
    await v.wait_until(lambda v: v.relative_alt is not None and v.relative_alt > z - 0.2, 30.0, "up")
    await v.goto_enu(x, y, z)
    try:  # within the controller's reach radius (1 m) of the point, as a task counts as reached
        await v.wait_until(lambda v: v.enu is not None and math.dist(v.enu, (x, y, z)) < 1.0, 30.0, "there")
    except TimeoutError as exc:
        raise AssertionError(f"{exc}: at {v.enu}, mode {v.mode}, "
                             f"positions held back {v.positions_held}") from None


@pytest.mark.parametrize(
    ("autopilot", "params", "mode"),
    [
        ("px4", {"NAV_DLL_ACT": 2, "COM_DL_LOSS_T": 2.5}, Mode.RTL),
        ("ardupilot", {"FS_GCS_ENABLE": 5, "FS_GCS_TIMEOUT": 2.5}, Mode.LAND),
        ("ardupilot", {"FS_GCS_ENABLE": 7, "FS_GCS_TIMEOUT": 2.5}, Mode.HOLD),
        ("px4", {"COM_DL_LOSS_T": 2.5}, None),  # NAV_DLL_ACT 0: disabled, the rover flies on
    ],
)
@pytest.mark.slow
async def test_a_link_loss_triggers_the_configured_action(
    autopilot: str, params: dict[str, float], mode: Mode | None, tmp_path: Path
) -> None:
    d = mission_dict(rovers=1, speedup=5.0)
    async with sim_fleet(d, autopilot=autopilot) as sim:
        async with await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0) as fleet:
            r1 = fleet.rovers["r1"]
            for name, value in params.items():
                await set_param(r1, name, value)
            await _airborne(r1)
            before = sim.vehicle("r1").mode
            sim.dropout("r1")  # deaf and silent: the controller's heartbeats no longer arrive
            if mode is None:
                await asyncio.sleep(4.0)  # longer than COM_DL_LOSS_T
                assert sim.vehicle("r1").mode is before and not sim.rover("r1").on_ground
                return
            await sim.wait_for(lambda: sim.vehicle("r1").mode is mode, 10.0)
            texts = [t for _t, _s, t in sim.vehicle("r1").statustexts]
            assert f"Failsafe: GCS link lost, {mode.value}" in texts
            if mode is Mode.RTL:  # back to where it armed (the carrier's deck position then)
                await sim.wait_for(lambda: sim.rover("r1").on_ground, 20.0)
                assert math.dist(sim.rover("r1").position[:2], sim.vehicle("r1").home[:2]) < 0.5


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
async def test_fence_upload_download_round_trip(autopilot: str, tmp_path: Path) -> None:
    d = mission_dict(rovers=1)
    mission = mission_from(d, tmp_path)
    fence = GeofenceConfig(SQUARE, (((20.0, 0.0), (25.0, 0.0), (25.0, 5.0)),), 20.0, "rtl")
    assert mission.origin is not None
    async with sim_fleet(d, autopilot=autopilot) as sim:
        async with await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
            r1 = fleet.rovers["r1"]
            await upload_fence(r1, fence, mission.origin)
            got = await download_fence(r1)
            sent = fence_items(fence, mission.origin)
            assert len(got) == 7 and all(a.same_as(b) for a, b in zip(sent, got, strict=True))
            assert (
                got[0].command == 5001
                and got[0].param1 == 4
                and got[4].command == 5002
                and got[4].param1 == 3
            )
            assert all(
                it.command < 5000 for it in await r1.download_mission()
            )  # the flight mission: untouched
            sv = sim.vehicle("r1")
            assert len(sv.fence.inclusions) == 1 and len(sv.fence.exclusions) == 1
            expect = (
                {"GF_ACTION": 3.0, "GF_MAX_VER_DIST": 20.0}
                if autopilot == "px4"
                else {"FENCE_ENABLE": 1.0, "FENCE_ACTION": 1.0, "FENCE_TYPE": 5.0, "FENCE_ALT_MAX": 20.0}
            )
            assert {k: sv.flavour.params[k] for k in expect} == expect
            await r1.link.clear_mission(r1.sysid, compid=r1.compid, mission_type=FENCE)
            assert await download_fence(r1) == [] and not sv.fence.has_zones


async def test_px4_mission_mode_refused_for_now_after_the_first_fence_is_asked_again(tmp_path: Path) -> None:
    """PX4 1.18 SITL refuses the mission mode with MAV_RESULT_TEMPORARILY_REJECTED for ~0.4 s after
    its first fence upload (measured; sitl Flavour.fence_load_time): a plain switch fails at once,
    ``set_mode(settle=...)`` asks again until it is taken, and ``start_mission`` does so on PX4."""
    from pymavlink.dialects.v20 import ardupilotmega as m

    from fleetctl.mavlink.messages import MissionItem
    from fleetctl.mavlink.vehicle import CommandRejected

    d = mission_dict(rovers=2, speedup=1.0)  # real time: the refusal lasts 0.45 s of wall time
    mission = mission_from(d, tmp_path)
    fence = GeofenceConfig(SQUARE, (), 20.0, "land")
    assert mission.origin is not None
    lat, lon = int(mission.origin.lat * 1e7), int(mission.origin.lon * 1e7)
    item = MissionItem(m.MAV_CMD_NAV_WAYPOINT, x=lat, y=lon, z=5.0)
    async with sim_fleet(d, autopilot="px4") as sim:
        async with await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
            r1 = fleet.rovers["r1"]
            await upload_fence(r1, fence, mission.origin)
            await r1.upload_mission([item, item])
            with pytest.raises(CommandRejected, match="TEMPORARILY_REJECTED"):
                await r1.set_mode("MISSION")
            await r1.set_mode("MISSION", settle=2.0)
            assert r1.mode_retries >= 1 and sim.vehicle("r1").mode is Mode.MISSION
            r2 = fleet.rovers["r2"]
            await upload_fence(r2, fence, mission.origin)
            await r2.upload_mission([item, item])
            await r2.start_mission()
            assert r2.mode_retries >= 1 and sim.vehicle("r2").mode is Mode.MISSION


def test_the_mission_mode_retry_is_documented() -> None:
    from fleetctl.mavlink.autopilots.px4 import MISSION_CHECK_S
    from fleetctl.mavlink.vehicle import MODE_RETRY_S
    from sitl.flavour import FIRST_FENCE_LOAD_S

    doc = " ".join((Path(__file__).resolve().parents[2] / "docs" / "autopilots.md").read_text().split())
    assert f"asked again every {MODE_RETRY_S:g} s for up to {MISSION_CHECK_S:g} s" in doc
    assert f"{MISSION_CHECK_S:g} mission seconds, `MODE_RETRY_S` {MODE_RETRY_S:g} s apart" in doc
    assert f"refuses the same way for {FIRST_FENCE_LOAD_S:g} s after a vehicle's first fence" in doc


@pytest.mark.parametrize(
    ("autopilot", "action", "goto", "mode", "breach"),
    [
        ("px4", "rtl", (5.0, -45.0, 6.0), Mode.RTL, "FENCE_BREACH_BOUNDARY"),
        (
            "ardupilot",
            "land",
            (22.0, 1.0, 6.0),
            Mode.LAND,
            "FENCE_BREACH_BOUNDARY",
        ),  # into the exclusion zone
        ("ardupilot", "hold", (10.0, 0.0, 25.0), Mode.HOLD, "FENCE_BREACH_MAXALT"),
    ],
)
async def test_a_breach_does_the_action_and_is_an_event(
    autopilot: str, action: str, goto: tuple[float, ...], mode: Mode, breach: str, tmp_path: Path
) -> None:
    d = mission_dict(rovers=1, speedup=5.0)
    mission = mission_from(d, tmp_path)
    fence = GeofenceConfig(SQUARE, (((20.0, -2.0), (25.0, -2.0), (25.0, 5.0), (20.0, 5.0)),), 20.0, action)
    assert mission.origin is not None
    async with sim_fleet(d, autopilot=autopilot) as sim:
        async with await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
            r1 = fleet.rovers["r1"]
            events: list[VehicleEvent] = []
            r1.add_listener(lambda ev: events.append(ev) if ev.kind == "geofence_breach" else None)
            await upload_fence(r1, fence, mission.origin)
            await _airborne(r1, 5.0, -10.0, 6.0)
            assert not events and not sim.vehicle("r1").fence_breach
            await r1.goto_enu(*goto)
            await sim.wait_for(lambda: sim.vehicle("r1").mode is mode, 20.0)
            await r1.wait_until(lambda v: v.fence_breach_count > 0, 3.0, "FENCE_STATUS breach")
            await asyncio.sleep(0.3)
    assert [ev.data["breach"] for ev in events] == [breach]
    assert any(t.startswith("Geofence breach") for _t, _s, t in sim.vehicle("r1").statustexts)


def _plan(
    carrier_path: list[tuple[float, float, float]], rover_path: list[tuple[float, float, float]]
) -> Plan:
    stop = Stop(carrier_path[-1], carrier_path, [RoverLeg("r1", rover_path, task="t1")])
    return Plan("deploy", "test", carrier_path[0], 0.0, [stop])


def test_plans_are_checked_against_the_fence() -> None:
    fence = GeofenceConfig(SQUARE, (((20.0, -2.0), (25.0, -2.0), (25.0, 5.0), (20.0, 5.0)),), 10.0, "report")
    ok = _plan([(0, 0, 0), (10, 0, 0)], [(10, 0, 0), (15, 20, 5)])
    assert plan_violations(ok, fence) == []
    check_plan(ok, fence)
    check_plan(ok, None)
    out = _plan([(0, 10, 0), (80, 10, 0)], [(80, 10, 0), (15, 20, 5)])
    assert plan_violations(out, fence) == [
        "carrier stop 1 at (80.0, 10.0) is outside the geofence",
        "the carrier's path to stop 1 leaves the geofence",
        "rover r1's path to task t1 (stop 1) leaves the geofence",
    ]
    through = _plan([(0, 0, 0), (10, 0, 0)], [(10, 0, 0), (35, 0, 12)])
    assert plan_violations(through, fence) == [
        "rover r1's path to task t1 (stop 1) crosses exclusion zone obstacles[0]",
        "rover r1's path to task t1 (stop 1) climbs to 12.0 m, above the geofence alt_max 10 m",
    ]
    with pytest.raises(
        ExecutionError, match="the deploy plan \\(test\\) leaves the geofence: carrier stop 1"
    ):
        check_plan(out, fence)


async def test_a_plan_leaving_the_fence_is_not_flown(tmp_path: Path) -> None:
    # a comb-shaped fence: the start and both tasks inside, joined by a detour the planners do not fly
    corridor = (
        LineString([(0, 0), (0, 30), (20, 30), (20, 10)])
        .union(LineString([(20, 30), (45, 30), (45, -10), (40, -10)]))
        .buffer(1.5, cap_style="square")
    )
    zone = unary_union([corridor, box(-3, -3, 3, 3), box(17, 7, 23, 13), box(37, -13, 43, -7)])
    d = mission_dict(rovers=2)
    d["geofence"] = {"polygon": [[round(x, 3), round(y, 3)] for x, y in zone.exterior.coords[:-1]]}
    out = await asyncio.wait_for(execute(mission_from(d, tmp_path), "deploy", runs_dir=tmp_path / "runs"), 60)
    assert out.exit_code == 1 and out.error is not None
    assert "plan" in out.error and "leaves the geofence" in out.error and "rover r" in out.error
    assert out.summary["tasks_reached"] == []


def test_a_line_is_clear_of_the_obstacles_and_inside_the_fence() -> None:
    """``line_clear``: what a rover sent straight over the carrier (off its planned path) must keep."""
    from types import SimpleNamespace
    from typing import cast

    from fleetctl.mission import Mission

    square = ((0.0, 0.0), (50.0, 0.0), (50.0, 50.0), (0.0, 50.0))
    block = ((20.0, 20.0), (30.0, 20.0), (30.0, 30.0), (20.0, 30.0))
    open_air = cast(Mission, SimpleNamespace(obstacles=(), geofence=None))
    fenced = cast(Mission, SimpleNamespace(obstacles=(block,), geofence=GeofenceConfig(square, (block,))))
    assert line_clear(open_air, (10.0, 10.0, 3.0), (90.0, 90.0, 0.0))
    assert line_clear(fenced, (10.0, 10.0, 3.0), (15.0, 40.0, 0.0))
    assert not line_clear(fenced, (10.0, 10.0, 3.0), (40.0, 40.0, 0.0))  # through the block
    assert not line_clear(fenced, (10.0, 10.0, 3.0), (60.0, 10.0, 0.0))  # out of the fence
