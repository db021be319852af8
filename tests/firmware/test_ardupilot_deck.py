"""The marsupial deck on real ArduPilot firmware: an ArduRover carrier and ArduCopter rovers on ONE
``sitl.json_physics`` world, the copters riding on the carrier's deck (0.5 m up, 1.5 m radius).

fleetctl's command line flies a deployment with several carrier stops (two groups of tasks 70 m
apart, ``rovers.deploy_range`` 25 m): the carrier drives with the rovers on its deck, they take off
from the deck at its stops and reach their tasks. The rovers then land where they are and wait for
the collection on the ground; their battery (``endurance_range`` 100 m) cannot fly them from one
group to a stop at the other, so the collection stops at each group: the rovers picked up first
ride on the deck to the second stop, and every rover ends on the deck, disarmed. Skipped with one
line without ``FLEETCTL_ARDUPILOT_DIR``.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from ardupilot_team import SPEEDUP, horizontal, land_where_they_are, probe
from deck_team import DECK, TASKS, Rides, check_deploy_rides, deck_team, ne_to_enu, plan_stops, sim_time
from pymavlink.dialects.v20 import ardupilotmega as M

pytestmark = pytest.mark.firmware

AT_TASK = 2.0  # m from the task, horizontally


def test_multi_stop_deploy_and_collect_on_the_deck(tmp_path: Path) -> None:
    with deck_team(tmp_path) as (team, world):
        t0, w0 = sim_time(world), time.monotonic()
        with Rides(world, team.rovers) as ride_deploy:
            proc, deploy = team.fly("deploy", timeout=400)
        t1, w1 = sim_time(world), time.monotonic()
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        assert deploy["result"] == "complete", deploy
        assert plan_stops(deploy) >= 2
        check_deploy_rides(deploy, ride_deploy)
        tasks = dict(TASKS)
        for task, rover in deploy["assignment"].items():   # the physics' positions, not the EKF's
            p = ne_to_enu(world.state(rover).position)
            assert world.on_deck(rover) is None and horizontal(p, tasks[task]) < AT_TASK, (rover, task, p)
            assert abs(p[2] - tasks[task][2]) < 0.5, (rover, task, p)   # task height above the ground

        land_where_they_are(team.fleet.gcs_port, [11 + k for k in range(len(team.rovers))])
        with Rides(world, team.rovers) as ride_collect:
            proc, collect = team.fly("collect", timeout=400)
        t2, w2 = sim_time(world), time.monotonic()
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        assert collect["result"] == "complete" and sorted(collect["rovers_loaded"]) == team.rovers, collect
        assert plan_stops(collect) >= 2
        assert ride_collect.boarded == set(team.rovers), ride_collect.boarded   # came down on the deck
        # the rovers picked up at the first stop rode to the next on the deck
        assert any(d > 20.0 for d in ride_collect.carried.values()), ride_collect.carried
        seen = probe(team.fleet.gcs_port, 4.0)
        c = world.state("carrier").position
        for k, rid in enumerate(team.rovers):   # on the deck: riding the carrier, landed and disarmed
            p = world.state(rid).position
            assert world.on_deck(rid) == "carrier", (rid, p, c)
            assert math.hypot(p[0] - c[0], p[1] - c[1]) <= DECK.radius, (rid, p, c)
            assert p[2] == c[2] - DECK.height, (rid, p, c)
            s = seen[11 + k]
            assert s.armed is False and s.landed_state in (None, M.MAV_LANDED_STATE_ON_GROUND), (rid, s)
        rode = {r: round(horizontal(ne_to_enu(world.state(r).position), tasks[t]), 1)
                for t, r in deploy["assignment"].items()}
        carried = {r: round(d, 1) for r, d in ride_deploy.carried.items()}
        carried_back = {r: round(d, 1) for r, d in ride_collect.carried.items()}
        print(f"\nArduPilot on the json_physics deck: deploy ({plan_stops(deploy)} stops) flown "
              f"{deploy['makespan_flown']:.1f} s vs planned {deploy['makespan_planned']:.1f} s; collect "
              f"({plan_stops(collect)} stops) {collect['makespan_flown']:.1f} s vs "
              f"{collect['makespan_planned']:.1f} s; rovers now this far from their tasks (m): {rode}; "
              f"carried on the deck (m): deploy {carried}, collect {carried_back}; "
              f"physics clock per command: deploy {t1 - t0:.1f} s in {w1 - w0:.1f} s wall, collect "
              f"{t2 - t1:.1f} s in {w2 - w1:.1f} s wall (--speedup {SPEEDUP:g})")
