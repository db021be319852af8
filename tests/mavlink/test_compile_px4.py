"""PX4 in compiled missions: a waypoint's acceptance radius (param2) is set, so that "reached"
means at the point (PX4's NAV_ACC_RAD default counts a multicopter's waypoint 10 m early)."""

from __future__ import annotations

from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as M

import planners
from fleetctl.mavlink.autopilots import Px4
from fleetctl.mavlink.autopilots.base import SPEED_QUANTITIES, Autopilot
from fleetctl.mavlink.compile import compile_plan
from fleetctl.mission import load_mission

RECON = Path(__file__).resolve().parents[2] / "missions" / "recon.yaml"


def test_px4_waypoints_carry_the_acceptance_radius_other_items_do_not() -> None:
    mission = load_mission(RECON)
    for plan in (planners.DEPLOY_PLANNERS["lee"](mission.deploy_problem()),
                 planners.COLLECT_PLANNERS["lee"](mission.collect_problem())):
        aps = {"carrier": Px4(M.MAV_TYPE_GROUND_ROVER),
               **{r: Px4(M.MAV_TYPE_QUADROTOR) for r in mission.rovers.ids}}
        compiled = compile_plan(plan, mission.origin, autopilot=aps)
        items = [*compiled.carrier, *(it for rm in compiled.rovers.values() for it in rm.items)]
        wps = [it for it in items if it.command == M.MAV_CMD_NAV_WAYPOINT]
        assert wps and all(it.param2 == Px4.acceptance_radius for it in wps)
        assert all(it.param2 == 0.0 for it in items if it.command != M.MAV_CMD_NAV_WAYPOINT)
        generic = compile_plan(plan, mission.origin, autopilot=None)
        assert all(it.param2 == 0.0 for it in generic.carrier)


def test_px4_speed_params_name_each_quantity_once_first() -> None:
    assert Autopilot().speed_params() == ()
    for ap in (Px4(M.MAV_TYPE_QUADROTOR), Px4(M.MAV_TYPE_GROUND_ROVER)):
        table = ap.speed_params()
        assert table and all(p.quantity in SPEED_QUANTITIES for p in table)
        # SI units; the land detector's threshold is a fraction of the landing speed
        assert all(p.scale == 1.0 for p in table if p.name != "LNDMC_Z_VEL_MAX")
        assert len({p.name for p in table}) == len(table)
    first = {}
    for p in Px4(M.MAV_TYPE_QUADROTOR).speed_params():
        first.setdefault(p.quantity, p.name)
    assert first == {"max_speed": "MPC_XY_CRUISE", "accel": "MPC_ACC_HOR", "climb_rate": "MPC_TKO_SPEED",
                     "land_speed": "MPC_LAND_SPEED"}
    assert {p.quantity for p in Px4(M.MAV_TYPE_GROUND_ROVER).speed_params()} == {"max_speed", "accel"}
