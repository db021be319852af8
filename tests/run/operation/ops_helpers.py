"""A small long operation on the embedded simulated fleet: 6 tasks (two worked landed), 2 rovers,
short durations, a battery swap, a high speed-up."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

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
