"""fleetctl.mavlink.compile: plan → mission items (coordinates through fleetctl.geo, item sequences)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

import planners
from fleetctl.mavlink.autopilots import ArduPilot, Px4
from fleetctl.mavlink.compile import CompileError, compile_plan, item_position, with_meeting_hold
from fleetctl.mavlink.link import MissionItem
from fleetctl.mission import load_mission
from fleetctl.mission.flight import TAKEOFF_HEIGHT
from planners.core.plan import Plan

RECON = Path(__file__).resolve().parents[2] / "missions" / "recon.yaml"
WP, LOITER, TAKEOFF, LAND = (M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LOITER_UNLIM, M.MAV_CMD_NAV_TAKEOFF,
                             M.MAV_CMD_NAV_LAND)


@pytest.fixture(scope="module")
def recon():
    mission = load_mission(RECON)
    deploy = planners.DEPLOY_PLANNERS["lee"](mission.deploy_problem())
    collect = planners.COLLECT_PLANNERS["lee"](mission.collect_problem())
    return mission, deploy, collect


def close_to(item, point, origin, tol=0.01) -> bool:
    return math.dist(item_position(item, origin), point) <= tol


def test_deploy_items_round_trip_to_the_plan(recon) -> None:
    mission, plan, _ = recon
    origin = mission.origin
    c = compile_plan(plan, origin, carrier_id="carrier")
    assert c.kind == "deploy" and len(c.stops) == len(plan.stops)
    items = list(c.carrier)
    assert all(i.frame == M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT for i in items)
    seq = 0
    for k, (stop, si) in enumerate(zip(plan.stops, c.stops, strict=True)):
        for v in stop.carrier_path[1:-1]:
            assert items[seq].command == WP and close_to(items[seq], (v[0], v[1], 0.0), origin)
            seq += 1
        assert (si.arrive_seq, si.hold_seq) == (seq, seq + 1)
        assert items[seq].command == WP and items[seq + 1].command == LOITER
        for s in (seq, seq + 1):
            assert close_to(items[s], (stop.position[0], stop.position[1], 0.0), origin)
        assert si.release_seq == (seq + 2 if k + 1 < len(plan.stops) else None)
        assert si.rovers == tuple(leg.rover for leg in stop.rovers)
        seq += 2
    assert seq == len(items)
    legs = plan.legs()
    assert set(c.rovers) == {leg.rover for leg in legs}
    for leg in legs:
        rm = c.rovers[leg.rover]
        cmds = [i.command for i in rm.items]
        assert cmds == [TAKEOFF] + [WP] * (len(leg.path) - 1) + [LOITER]
        assert rm.task == leg.task and rm.target_seq == len(cmds) - 2 and rm.final_seq == len(cmds) - 1
        start, target = leg.path[0], leg.end
        # take off to the clearance only, then the straight line to the task
        assert close_to(rm.items[0], (start[0], start[1], TAKEOFF_HEIGHT), origin)
        for item, v in zip(rm.items[1:-1], leg.path[1:], strict=True):
            assert close_to(item, v, origin)  # 3D, within 1 cm
        assert close_to(rm.items[-1], target, origin)
        assert rm.items[-2].z == pytest.approx(target[2])


def test_collect_items(recon) -> None:
    mission, _, plan = recon
    origin = mission.origin
    c = compile_plan(plan, origin, meet_height=3.0)
    for k, stop in enumerate(plan.stops):
        for leg in stop.rovers:
            rm = c.rovers[leg.rover]
            assert rm.stop == k and rm.task is None
            cmds = [i.command for i in rm.items]
            meet_z = max(3.0, leg.end[2])
            takeoff = [TAKEOFF] if leg.path[0][2] <= 0.2 else []
            assert cmds == takeoff + [WP] * (len(leg.path) - 2) + [WP, LAND]
            for item, v in zip(rm.items[len(takeoff):rm.target_seq], leg.path[1:-1], strict=True):
                assert close_to(item, v, origin)
            assert close_to(rm.items[rm.target_seq], (stop.position[0], stop.position[1], meet_z), origin)
            assert close_to(rm.items[rm.final_seq], (stop.position[0], stop.position[1], 0.0), origin)
            assert rm.final_seq == len(cmds) - 1 and cmds[-1] == LAND


def test_collect_from_the_ground_takes_off_first() -> None:
    from fleetctl.geo import Origin
    from planners.core.plan import Plan, RoverLeg, Stop

    origin = Origin(47.397742, 8.545594, 488.0)
    stop = Stop((10.0, 0.0, 0.0), [(0.0, 0.0, 0.0), (10.0, 0.0, 0.0)],
                [RoverLeg("r1", [(5, 5, 0), (10, 0, 0)])])
    rm = compile_plan(Plan("collect", "x", (0, 0, 0), 0.0, [stop]), origin, meet_height=4.0).rovers["r1"]
    assert [i.command for i in rm.items] == [TAKEOFF, WP, LAND]
    assert close_to(rm.items[0], (5, 5, TAKEOFF_HEIGHT), origin) and rm.target_seq == 1


def test_ardupilot_item_0_is_home_and_indices_count_it(recon) -> None:
    mission, plan, _ = recon
    px4 = compile_plan(plan, mission.origin, autopilot=None)  # no home item (as PX4, without its param2)
    apm = compile_plan(plan, mission.origin, autopilot={"carrier": ArduPilot(M.MAV_TYPE_GROUND_ROVER),
                                                        **{r: ArduPilot() for r in mission.rovers.ids}})
    assert len(apm.carrier) == len(px4.carrier) + 1
    home = apm.carrier[0]
    assert home.frame == M.MAV_FRAME_GLOBAL and close_to(home, (*plan.start[:2], 0.0), mission.origin)
    # the same items but for param4 (yaw): ArduPilot takes NaN only on WAYPOINT/LAND/TAKEOFF
    def yawless(it: MissionItem) -> MissionItem:
        return dataclasses.replace(it, param4=0.0)

    assert all(yawless(a).same_as(yawless(b)) for a, b in zip(apm.carrier[1:], px4.carrier, strict=True))
    for a, b in zip(apm.stops, px4.stops, strict=True):
        assert (a.arrive_seq, a.hold_seq) == (b.arrive_seq + 1, b.hold_seq + 1)
    for rid, rm in apm.rovers.items():
        assert rm.items[0].frame == M.MAV_FRAME_GLOBAL and rm.target_seq == px4.rovers[rid].target_seq + 1
        pairs = zip(rm.items[1:], px4.rovers[rid].items, strict=True)
        assert all(yawless(a).same_as(yawless(b)) for a, b in pairs)
    nan_ok = {M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_NAV_LAND}
    every = [*apm.carrier, *(it for rm in apm.rovers.values() for it in rm.items)]
    assert {it.command for it in every if math.isnan(it.param4)} <= nan_ok
    assert any(it.command == M.MAV_CMD_NAV_LOITER_UNLIM and it.param4 == 0.0 for it in every)
    # PX4 keeps NaN (= keep the heading) on the hold
    assert all(math.isnan(it.param4) for it in px4.carrier if it.command == M.MAV_CMD_NAV_LOITER_UNLIM)


def test_a_collection_hold_above_the_meeting_point_is_valid_for_its_firmware(recon) -> None:
    mission, plan, _ = recon
    stop = plan.stops[0]
    leg = stop.rovers[0]
    cplan = Plan("collect", "x", plan.start, 0.0, [dataclasses.replace(
        stop, rovers=[dataclasses.replace(leg, path=[(5.0, 5.0, 6.0), (*stop.position[:2], 3.0)])])])
    for ap, yaw in ((ArduPilot(), 0.0), (Px4(), math.nan)):
        rm = compile_plan(cplan, mission.origin, autopilot=ap).rovers[leg.rover]
        items, hold, land = with_meeting_hold(rm, ap)
        assert items[hold].command == M.MAV_CMD_NAV_LOITER_UNLIM and items[land].command == M.MAV_CMD_NAV_LAND
        assert (items[hold].x, items[hold].y, items[hold].z) == (items[hold - 1].x, items[hold - 1].y,
                                                                 items[hold - 1].z)
        assert items[hold].param4 == yaw or (math.isnan(yaw) and math.isnan(items[hold].param4))


def test_home_height_shifts_relative_heights(recon) -> None:
    mission, plan, _ = recon
    a = compile_plan(plan, mission.origin)
    b = compile_plan(plan, mission.origin, home_height=2.0)
    leg = plan.legs()[0]
    assert b.rovers[leg.rover].items[-1].z == pytest.approx(a.rovers[leg.rover].items[-1].z - 2.0)
    assert math.dist(item_position(b.rovers[leg.rover].items[-1], mission.origin, home_height=2.0),
                     leg.end) < 0.01


def test_a_rover_whose_home_is_on_the_deck_flies_to_the_task_height_and_takes_off_above_it(recon) -> None:
    """Per-rover home heights (a copter booted on a 0.5 m deck): the task stays at its height
    above the ground, the take-off clearance is above the deck, other vehicles keep 0."""
    mission, plan, _ = recon
    legs = plan.legs()
    deck, ground = legs[0].rover, legs[1].rover
    c = compile_plan(plan, mission.origin, home_height={deck: 0.5})
    rm = c.rovers[deck]
    assert rm.home_height == 0.5 and c.rovers[ground].home_height == 0.0
    assert math.dist(item_position(rm.items[-1], mission.origin, rm.home_height), legs[0].end) < 0.01
    takeoff = next(it for it in rm.items if it.command == TAKEOFF)
    assert takeoff.z == pytest.approx(TAKEOFF_HEIGHT)  # above home: the deck it sits on
    flat = compile_plan(plan, mission.origin).rovers[ground]
    assert c.rovers[ground].items[-1].z == pytest.approx(flat.items[-1].z)


def test_no_origin_is_an_error(recon) -> None:
    _, plan, _ = recon
    with pytest.raises(CompileError, match="origin"):
        compile_plan(plan, None)
