"""A small two-team mission on the simulated fleet (carriers c1 and c2, two rovers each)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml

from fleetctl.mission import Mission, load_mission

ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}
CARRIER = {"connection": "sim", "heading_deg": 0, "max_speed": 10.0, "accel": 5.0, "turn_rate": None,
           "unload_time": 1.0, "load_time": 1.0}

TWO_TEAMS: dict[str, Any] = {
    "name": "twoteams",
    "origin": ORIGIN,
    "carriers": [
        {"id": "c1", "sysid": 1, "position": [0, 0], **CARRIER, "fleet": {"count": 2, "sysid_start": 11}},
        {"id": "c2", "sysid": 2, "position": [80, 0], **CARRIER, "fleet": {"count": 2, "sysid_start": 31}},
    ],
    "rovers": {"max_speed": 5.0, "accel": None, "deploy_range": 40.0, "endurance_range": 600.0,
               "reserve": 0.1},
    "tasks": [{"id": "t1", "position": [-10, 20, 5]}, {"id": "t2", "position": [10, 30, 4]},
              {"id": "t3", "position": [75, 25, 5]}, {"id": "t4", "position": [95, 20, 4]}],
    "sim": {"speedup": 20.0, "faults": []},
    "links": {"heartbeat_timeout": 3.0},
    "dwell": 2.0,
}


def two_teams(**changes: Any) -> dict[str, Any]:
    d = copy.deepcopy(TWO_TEAMS)
    d.update(copy.deepcopy(changes))
    return d


def write_mission(d: dict[str, Any], path: Path) -> Path:
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    return path


def mission_from(d: dict[str, Any], tmp_path: Path, name: str = "teams.yaml") -> Mission:
    return load_mission(write_mission(d, tmp_path / name))
