"""A small long operation on the embedded simulated fleet: 6 tasks (two worked landed), 2 rovers,
short durations, a battery swap, a high speed-up."""

from __future__ import annotations

import asyncio
import copy
import json
from pathlib import Path
from typing import Any

from sitl import SimFleet
from sitl.world import Phase as BodyPhase
from tests.run.ctl_helpers import ORIGIN

SMALL_OPERATION: dict[str, Any] = {
    "name": "small-operation",
    "origin": ORIGIN,
    "operation": True,
    "carrier": {"id": "carrier", "connection": "sim", "sysid": 1, "position": [0, 0], "heading_deg": 45,
                "max_speed": 10.0, "accel": 2.0, "turn_rate": 1.0, "unload_time": 2.0, "load_time": 2.0,
                "swap_time": 10.0},
    "rovers": {"max_speed": 5.0, "accel": 3.0, "deploy_range": 80.0, "endurance_range": 600.0, "reserve": 0.1,
               # the take-off clearance these scenarios' batteries were set against (the default,
               # a 1 m climb at accel 3, is 1.25 s)
               "takeoff_time": 0.3, "fleet": {"count": 2, "sysid_start": 11}},
    "dwell": 20.0,
    "tasks": [
        {"id": "t1", "position": [20, 30, 4], "duration": 20},
        {"id": "t2", "position": [35, 10, 4], "duration": 30},
        {"id": "t3", "position": [60, 40, 0], "duration": 25, "work": "ground"},
        {"id": "t4", "position": [80, 20, 4], "duration": 15},
        {"id": "t5", "position": [50, -20, 4], "duration": 40},
        {"id": "t6", "position": [10, -30, 0], "duration": 20, "work": "ground"},
    ],
    "sim": {"speedup": 20.0, "faults": []},
    "links": {"heartbeat_timeout": 3.0},
}


def small_operation(**changes: Any) -> dict[str, Any]:
    d = copy.deepcopy(SMALL_OPERATION)
    d.update(changes)
    return d


def journal(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "journal.jsonl").read_text().splitlines()]


async def until_journalled(run_dir: Path, kind: str, cause: str = "",
                           timeout: float = 90.0) -> dict[str, Any]:
    """The first record of ``kind`` whose cause holds ``cause`` in a run's journal, once it is written
    (looked for every 50 ms; a line still being written is read at the next look); TimeoutError
    after ``timeout`` wall seconds."""
    path = run_dir / "journal.jsonl"
    async with asyncio.timeout(timeout):
        while True:
            lines = path.read_text().splitlines() if path.exists() else []
            for line in lines:
                try:
                    r = json.loads(line)
                except json.JSONDecodeError:
                    break
                if r.get("kind") == kind and cause in str(r.get("cause", "")):
                    return r
            await asyncio.sleep(0.05)


async def drop_battery(sim: SimFleet, rover: str, level: float, run_dir: Path, after: float = 0.0) -> None:
    """Set ``rover``'s battery to ``level`` ``after`` mission seconds once it is in the air, and hold it
    there until the controller journals the replan the reading asks for ("rover <id> at ..."); then it
    drains on. From the take-off until that replan the fleet flies in real time: the controller and
    the simulated fleet share one event loop, and on a loaded machine (CI: two workers, firmware
    beside them) a reading was acted on up to 25 mission s late at 20x, with the rover drained
    and flown on meanwhile. The test asks how the controller reads a battery, not how fast the
    machine runs its event loop."""
    body = sim.rover(rover)
    await sim.wait_for(lambda: body.phase is BodyPhase.AIR, 60)
    speedup = sim.speedup
    sim.set_speedup(1.0)
    try:
        if after:
            await sim.wait_sim_time(sim.sim_time + after, 60)
        sim.pin_battery(rover, level)
        await until_journalled(run_dir, "replan", f"rover {rover} at")
        sim.pin_battery(rover, None)
    finally:
        sim.set_speedup(speedup)
