"""PX4 SITL (SIH) fleet for the firmware tests: a rover carrier (airframe 10045) and quadcopters
(10040) at the carrier's home, all on one ground-station port ``udpin://127.0.0.1:14550``.

:func:`px4_deck_fleet`: the same airframes flying on ``sitl.json_physics`` through PX4's
simulator interface instead of SIH, the quadcopters riding on the carrier's deck.

Also runnable by hand: ``FLEETCTL_PX4_DIR=/path/to/px4 python3 -m tests.firmware.px4_fleet OUTDIR``
starts the fleet, writes ``OUTDIR/mission.yaml`` and runs until interrupted (SIGINT/SIGTERM)."""

from __future__ import annotations

import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sitl.firmware import FirmwareFleet, FirmwareVehicle, find_px4
from sitl.json_physics import Deck, JsonWorld

ROOT = Path(__file__).resolve().parents[2]
HOME = (47.397742, 8.545594, 488.0, 0.0)  # the origin of the mission: lat, lon, AMSL alt, heading
GCS_PORT = 14550  # PX4 always sends its ground-station link here
SPEEDUP = 4.0  # PX4_SIM_SPEED_FACTOR (the machine is shared: keep it at most 4)
SKIP_REASON = "PX4 SITL not found: set FLEETCTL_PX4_DIR"
# tasks 20-30 m from the carrier, one per rover (east, north, height above ground)
TASKS = ((20.0, 8.0, 5.0), (-6.0, 24.0, 6.0), (-14.0, -18.0, 4.0))


DECK = Deck(height=0.5, radius=1.5)
DECK_SPEEDUP = 2.0  # the world's physics runs in Python: four vehicles at 250 Hz keep pace at 2x
DECK_INSTANCE_BASE = 30
SEATS = ((0.5, 0.5), (0.5, -0.5), (-0.5, 0.5), (-0.5, -0.5))  # forward, right of the carrier


def random_task_positions(seed: int, n: int = 3) -> tuple[tuple[float, float, float], ...]:
    """``n`` tasks fleetctl has never seen: 15-30 m from the carrier in random directions, 3-10 m up,
    at least 8 m apart (``ardupilot_team.random_tasks``, the ArduPilot tests' missions)."""
    from ardupilot_team import random_tasks

    return tuple(p for _id, p in random_tasks(seed, n))


def vehicles(n_rovers: int = 3) -> list[FirmwareVehicle]:
    out = [FirmwareVehicle("carrier", sysid=1, frame="rover", home=HOME)]
    out += [FirmwareVehicle(f"r{i + 1}", sysid=11 + i, frame="copter", home=HOME) for i in range(n_rovers)]
    return out


def cli(*args: str, timeout: float = 90.0,
        env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """``fleetctl`` as a user runs it (``env``: more environment variables)."""
    full = dict(os.environ, PYTHONPATH=str(ROOT), **(env or {}))
    return subprocess.run([sys.executable, "-m", "fleetctl.cli", *args], cwd=ROOT, env=full, text=True,
                          capture_output=True, timeout=timeout)


def wait_ready(mission: Path, timeout: float = 40.0,
               env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """``fleetctl status`` until it passes (armable after ~1.3 s at 4x: GPS fix, home, estimator) or
    ``timeout`` s; its last output."""
    deadline = time.monotonic() + timeout
    while True:
        out = cli("status", "-m", str(mission), "--timeout", "10", env=env)
        if out.returncode == 0 or time.monotonic() > deadline:
            return out
        time.sleep(1.0)


def port_free(port: int = GCS_PORT) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


@contextmanager
def px4_fleet(n_rovers: int = 3, speedup: float = SPEEDUP) -> Iterator[FirmwareFleet]:
    build = find_px4()
    if build is None:
        raise RuntimeError(SKIP_REASON)
    fleet = FirmwareFleet(build, vehicles(n_rovers), gcs_port=GCS_PORT, speedup=speedup)
    try:
        with fleet:
            yield fleet
    finally:
        fleet.cleanup()


@contextmanager
def px4_deck_fleet(n_rovers: int = 3, speedup: float = DECK_SPEEDUP,
                   instance_base: int = DECK_INSTANCE_BASE) -> Iterator[tuple[FirmwareFleet, JsonWorld]]:
    """PX4 on the marsupial deck: the carrier at the origin heading north, the quadcopters on its
    deck (:data:`SEATS`), one physics world (``sitl.json_physics``, PX4's simulator interface)."""
    build = find_px4()
    if build is None:
        raise RuntimeError(SKIP_REASON)
    world = JsonWorld(HOME[:3], instance_base=instance_base, firmware="px4", speed=speedup)
    world.add_carrier("carrier", 1, deck=DECK)
    for k in range(n_rovers):
        fwd, right = SEATS[k]
        world.add_copter(f"r{k + 1}", 11 + k, north=fwd, east=right, on_deck_of="carrier")
    fleet = FirmwareFleet(build, world.firmware_vehicles(), gcs_port=GCS_PORT, speedup=speedup,
                          instance_base=instance_base)
    try:
        with world, fleet:
            yield fleet, world
    finally:
        fleet.cleanup()


# the mission's rover speeds are PX4's defaults (written with firmware_speeds: set); the take-off and
# touch-down times and the leg acceleration the plan uses come from Px4.handling_times and
# Px4.planned_accel (measured: fleetctl/mavlink/autopilots/px4.py)
PX4_TIMING = {"max_speed": 5.0, "accel": 3.0}


def _task_id(i: int, task: Sequence[Any]) -> str:
    return str(task[0]) if len(task) == 4 else f"t{i + 1}"


def mission_yaml(tasks: Sequence[Sequence[Any]] = TASKS, *, n_rovers: int = 3,
                 extra_rovers: str = "", timing: dict[str, float] | None = None,
                 deploy_range: float | None = None, extra: str = "",
                 deck_height: float | None = None, endurance_range: float = 3000.0) -> str:
    """A mission for the PX4 fleet. ``tasks``: (east, north, up) or (id, east, north, up);
    ``deploy_range`` default: every task within reach of the carrier's start; ``extra``: more
    top-level keys; ``deck_height``: the carrier's deck above its reference point (:data:`DECK`
    for :func:`px4_deck_fleet`)."""
    t = {**PX4_TIMING, **(timing or {})}
    lat, lon, alt, _ = HOME
    task_lines = "".join(f"  - {{id: {_task_id(i, p)}, position: [{p[-3]:g}, {p[-2]:g}, {p[-1]:g}]}}\n"
                         for i, p in enumerate(tasks))
    reach = deploy_range or max(math.hypot(p[-3], p[-2]) for p in tasks) + 10.0
    deck = "" if deck_height is None else f"  deck_height: {deck_height:g}\n"
    return f"""name: px4-sitl
origin: {{lat: {lat}, lon: {lon}, alt: {alt}}}
carrier:
  id: carrier
  connection: udpin://127.0.0.1:{GCS_PORT}
  sysid: 1
  position: [0, 0]
  heading_deg: 0
  max_speed: 1.0             # RO_SPEED_LIM: below 1 m/s the Ackermann rover cannot turn to a stop behind it
  accel: 1.0
  unload_time: 0.0
  load_time: 0.0
{deck}rovers:  # PX4 quadcopter (10040) defaults, measured on SITL (tests/firmware/test_px4.py)
  max_speed: {t['max_speed']:g}               # MPC_XY_CRUISE
  accel: {t['accel']:g}                   # MPC_ACC_HOR
  climb_rate: 1.5            # MPC_TKO_SPEED
  land_speed: 0.7            # MPC_LAND_SPEED
  deploy_range: {reach:g}
  endurance_range: {endurance_range:g}
  reserve: 0.1
  fleet: {{count: {n_rovers}, sysid_start: 11}}
{extra_rovers}{extra}tasks:
{task_lines}"""


def main(argv: list[str]) -> int:
    out = Path(argv[1] if len(argv) > 1 else "px4-fleet")
    out.mkdir(parents=True, exist_ok=True)
    (out / "mission.yaml").write_text(mission_yaml())
    stop = False

    def on_signal(*_a: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    with px4_fleet() as fleet:
        print(f"PX4 fleet up (workdir {fleet.workdir}), pid {os.getpid()}", flush=True)
        while not stop:
            time.sleep(0.5)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
