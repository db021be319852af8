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
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import yaml
from ardupilot_team import (
    ORIGIN,
    SPEEDUP,
    Team,
    build,
    horizontal,
    journal,
    land_where_they_are,
    mission_yaml,
    probe,
)
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.firmware import FirmwareFleet
from sitl.json_physics import Deck, JsonWorld

pytestmark = pytest.mark.firmware

GCS_PORT = 14640
INSTANCE_BASE = 60
DECK = Deck(height=0.5, radius=1.5)
AT_TASK = 2.0  # m from the task, horizontally
FIRMWARE = {"SIM_RATE_HZ": 400}  # physics steps at the copter's loop rate
# two groups 70 m apart (ENU east, north, up): the carrier must stop at each
TASKS = (("a1", (45.0, 6.0, 6.0)), ("a2", (50.0, -8.0, 6.0)),
         ("b1", (40.0, 76.0, 6.0)), ("b2", (52.0, 70.0, 6.0)))
# where each copter sits on the deck (forward, right of the carrier's reference point)
SEATS = ((0.5, 0.5), (0.5, -0.5), (-0.5, 0.5), (-0.5, -0.5))


def deck_mission(n_rovers: int) -> dict[str, Any]:
    return mission_yaml(GCS_PORT, n_rovers, tasks=TASKS, extra={
        "carrier": {"max_speed": 3.0, "accel": 1.0},
        # a battery that cannot fly from one group to the other and back onto the deck: the
        # collection needs a stop at each group (the rovers wait for it on the ground)
        "rovers": {"deploy_range": 25.0, "endurance_range": 100.0},
    })


@contextmanager
def deck_team(tmp_path: Path, n_rovers: int = 4,
              mission: dict[str, Any] | None = None) -> Iterator[tuple[Team, JsonWorld]]:
    """The world (carrier at the origin heading north, copters on its deck), its firmware and the
    mission file (``mission``, else :func:`deck_mission`); ready when fleetctl's preflight passes."""
    b = build()
    world = JsonWorld(ORIGIN, instance_base=INSTANCE_BASE)
    world.add_carrier("carrier", 1, deck=DECK, firmware_params=FIRMWARE)
    rovers = [f"r{k + 1}" for k in range(n_rovers)]
    for k, r in enumerate(rovers):
        fwd, right = SEATS[k]
        world.add_copter(r, 11 + k, north=fwd, east=right, on_deck_of="carrier", firmware_params=FIRMWARE)
    path = tmp_path / "mission.yaml"
    path.write_text(yaml.safe_dump(mission or deck_mission(n_rovers), sort_keys=False))
    fleet = FirmwareFleet(b, world.firmware_vehicles(), gcs_port=GCS_PORT, speedup=SPEEDUP,
                          instance_base=INSTANCE_BASE, workdir=tmp_path / "firmware")
    with world, fleet:
        team = Team(fleet, path, tmp_path / "runs", rovers)
        team.wait_ready()
        yield team, world


def plan_stops(summary: dict[str, Any]) -> int:
    """The carrier stops of the run's plan (its journal's first ``plan`` record)."""
    rows = journal(Path(summary["journal"]).parent)
    return next(len(r["plan"]["stops"]) for r in rows if r.get("kind") == "plan" and "plan" in r)


class Rides:
    """Samples the physics from a thread while a command runs: how far the carrier drove each
    rover while it sat on the deck, and which rovers boarded (came down on the deck)."""

    def __init__(self, world: JsonWorld, rovers: list[str]) -> None:
        self.world, self.rovers = world, rovers
        self.carried = dict.fromkeys(rovers, 0.0)
        self.boarded: set[str] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        last = self.world.state("carrier").position
        aboard = {r: self.world.on_deck(r) == "carrier" for r in self.rovers}
        while not self._stop.wait(0.1):
            c = self.world.state("carrier").position
            step = math.hypot(c[0] - last[0], c[1] - last[1])
            for r in self.rovers:
                now = self.world.on_deck(r) == "carrier"
                if now and aboard[r]:
                    self.carried[r] += step
                if now and not aboard[r]:
                    self.boarded.add(r)
                aboard[r] = now
            last = c

    def __enter__(self) -> Rides:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(2.0)


def sim_time(world: JsonWorld) -> float:
    """The world's clock: the carrier's simulated seconds (the server keeps every firmware on it)."""
    return world.world.vehicles["carrier"].time


def ne_to_enu(p: tuple[float, float, float]) -> tuple[float, float, float]:
    return (p[1], p[0], -p[2])


def test_multi_stop_deploy_and_collect_on_the_deck(tmp_path: Path) -> None:
    with deck_team(tmp_path) as (team, world):
        t0, w0 = sim_time(world), time.monotonic()
        with Rides(world, team.rovers) as ride_deploy:
            proc, deploy = team.fly("deploy", timeout=400)
        t1, w1 = sim_time(world), time.monotonic()
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        assert deploy["result"] == "complete", deploy
        assert sorted(deploy["tasks_reached"]) == sorted(t for t, _ in TASKS)
        assert plan_stops(deploy) >= 2
        launched_later = [r for t, r in deploy["assignment"].items() if t.startswith("b")]
        assert all(ride_deploy.carried[r] > 30.0 for r in launched_later), ride_deploy.carried  # via stop 1
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
