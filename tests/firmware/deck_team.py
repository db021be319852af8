"""An ArduPilot team on the marsupial deck (``sitl.json_physics``): an ArduRover carrier and
ArduCopter rovers on ONE physics world, the copters riding on the carrier's deck (0.5 m up, 1.5 m
radius), for the deck's firmware tests and ``bench/firmware_deck.py``. Skips with one line without
``FLEETCTL_ARDUPILOT_DIR`` (:func:`ardupilot_team.build`)."""

from __future__ import annotations

import math
import random
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml
from ardupilot_team import ORIGIN, SPEEDUP, Team, build, horizontal, journal, mission_yaml

from sitl.firmware import FirmwareFleet
from sitl.json_physics import Deck, JsonWorld

GCS_PORT = 14640
INSTANCE_BASE = 60
DECK = Deck(height=0.5, radius=1.5)
FIRMWARE = {"SIM_RATE_HZ": 400}  # physics steps at the copter's loop rate
# two groups 70 m apart (ENU east, north, up): the carrier must stop at each
TASKS = (("a1", (45.0, 6.0, 6.0)), ("a2", (50.0, -8.0, 6.0)),
         ("b1", (40.0, 76.0, 6.0)), ("b2", (52.0, 70.0, 6.0)))
# where each copter sits on the deck (forward, right of the carrier's reference point)
SEATS = ((0.5, 0.5), (0.5, -0.5), (-0.5, 0.5), (-0.5, -0.5))
Tasks = Sequence[tuple[str, tuple[float, float, float]]]


def deck_mission(n_rovers: int, tasks: Tasks = TASKS, gcs_port: int = GCS_PORT) -> dict[str, Any]:
    return mission_yaml(gcs_port, n_rovers, tasks=tasks, extra={
        # the deck is 0.5 m above the carrier's reference point: a rover at rest on it is down
        "carrier": {"max_speed": 3.0, "accel": 1.0, "deck_height": DECK.height},
        # a battery that cannot fly from one group to the other and back onto the deck: the
        # collection needs a stop at each group (the rovers wait for it on the ground)
        "rovers": {"deploy_range": 25.0, "endurance_range": 100.0},
    })


def random_groups(seed: int) -> tuple[tuple[str, tuple[float, float, float]], ...]:
    """Four tasks in two groups of two, a mission fleetctl has never seen: group a 35-55 m from
    the carrier in a random direction, group b 60-80 m beyond it (each group's tasks 6-14 m apart,
    within 8 m of its centre), 3-8 m up."""
    rng = random.Random(seed)

    def centre(origin: tuple[float, float], lo: float, hi: float) -> tuple[float, float]:
        r, a = rng.uniform(lo, hi), rng.uniform(0.0, 2 * math.pi)
        return origin[0] + r * math.cos(a), origin[1] + r * math.sin(a)

    a = centre((0.0, 0.0), 35.0, 55.0)
    b = centre(a, 60.0, 80.0)
    out: list[tuple[str, tuple[float, float, float]]] = []
    for name, (cx, cy) in (("a", a), ("b", b)):
        while True:
            pair = [(round(cx + rng.uniform(-8, 8), 1), round(cy + rng.uniform(-8, 8), 1),
                     round(rng.uniform(3.0, 8.0), 1)) for _ in range(2)]
            if 6.0 <= horizontal(pair[0], pair[1]) <= 14.0:
                break
        out += [(f"{name}{k + 1}", p) for k, p in enumerate(pair)]
    return tuple(out)


@contextmanager
def deck_team(tmp_path: Path, n_rovers: int = 4, mission: dict[str, Any] | None = None, *,
              gcs_port: int = GCS_PORT,
              instance_base: int = INSTANCE_BASE) -> Iterator[tuple[Team, JsonWorld]]:
    """The world (carrier at the origin heading north, copters on its deck), its firmware and the
    mission file (``mission``, else :func:`deck_mission`); ready when fleetctl's preflight passes."""
    b = build()
    world = JsonWorld(ORIGIN, instance_base=instance_base)
    world.add_carrier("carrier", 1, deck=DECK, firmware_params=FIRMWARE)
    rovers = [f"r{k + 1}" for k in range(n_rovers)]
    for k, r in enumerate(rovers):
        fwd, right = SEATS[k]
        world.add_copter(r, 11 + k, north=fwd, east=right, on_deck_of="carrier", firmware_params=FIRMWARE)
    path = tmp_path / "mission.yaml"
    path.write_text(yaml.safe_dump(mission or deck_mission(n_rovers, gcs_port=gcs_port), sort_keys=False))
    fleet = FirmwareFleet(b, world.firmware_vehicles(), gcs_port=gcs_port, speedup=SPEEDUP,
                          instance_base=instance_base, workdir=tmp_path / "firmware")
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
    rover while it sat on the deck, which rovers boarded (came down on the deck), and how fast the
    carrier drove when each rover left its deck (m/s)."""

    def __init__(self, world: JsonWorld, rovers: list[str]) -> None:
        self.world, self.rovers = world, rovers
        self.carried = dict.fromkeys(rovers, 0.0)
        self.boarded: set[str] = set()
        self.left_at: dict[str, float] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        last = self.world.state("carrier").position
        aboard = {r: self.world.on_deck(r) == "carrier" for r in self.rovers}
        while not self._stop.wait(0.1):
            body = self.world.state("carrier")
            c, speed = body.position, math.hypot(body.velocity[0], body.velocity[1])
            step = math.hypot(c[0] - last[0], c[1] - last[1])
            for r in self.rovers:
                now = self.world.on_deck(r) == "carrier"
                if now and aboard[r]:
                    self.carried[r] += step
                if now and not aboard[r]:
                    self.boarded.add(r)
                if aboard[r] and not now:
                    self.left_at[r] = speed
                aboard[r] = now
            last = c

    def __enter__(self) -> Rides:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(2.0)


STANDING = 0.3  # m/s: a carrier this slow stands (fleetctl.run.carrier.STAY_SPEED)


def check_deploy_rides(deploy: dict[str, Any], ride: Rides) -> None:
    """A deployment of ``TASKS`` that used several stops: every task reached, the rovers of the
    second group (``b…``) carried on the deck from the first stop (more than 30 m), and every rover
    took off from a carrier standing on its stop (the physics' speed as it left the deck)."""
    assert sorted(deploy["tasks_reached"]) == sorted(t for t, _ in TASKS)
    launched_later = [r for t, r in deploy["assignment"].items() if t.startswith("b")]
    assert all(ride.carried[r] > 30.0 for r in launched_later), ride.carried  # via stop 1
    assert set(ride.left_at) == set(deploy["assignment"].values()), ride.left_at
    assert all(v <= STANDING for v in ride.left_at.values()), ride.left_at


def sim_time(world: JsonWorld) -> float:
    """The world's clock: the carrier's simulated seconds (the server keeps every firmware on it)."""
    return world.world.vehicles["carrier"].time


def ne_to_enu(p: tuple[float, float, float]) -> tuple[float, float, float]:
    return (p[1], p[0], -p[2])
