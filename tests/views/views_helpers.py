"""Helpers for the view tests: a small mission, a FleetState of it, and a run folder written by hand."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import yaml

from fleetctl.geo import Origin, enu_to_geodetic
from fleetctl.mavlink.tlog import tlog_record
from fleetctl.mission import Mission, load_mission
from fleetctl.run.state import FleetState

ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}

BASE: dict[str, Any] = {
    "name": "viewtest",
    "origin": ORIGIN,
    "carrier": {"id": "carrier", "connection": "sim", "sysid": 1, "position": [0, 0], "heading_deg": 0,
                "max_speed": 10.0, "accel": 5.0, "turn_rate": None, "unload_time": 1.0, "load_time": 1.0},
    "rovers": {"max_speed": 2.0, "accel": None, "deploy_range": 40.0, "endurance_range": 200.0,
               "reserve": 0.1, "fleet": {"count": 2, "sysid_start": 11}},
    "tasks": [{"id": "t1", "position": [20, 10, 5]}, {"id": "t2", "position": [40, -10, 4]}],
    "sim": {"speedup": 2.0, "faults": []},
    "links": {"heartbeat_timeout": 3.0},
}

CARRIER = {"connection": "sim", "heading_deg": 0, "max_speed": 10.0, "accel": 5.0, "turn_rate": None,
           "unload_time": 1.0, "load_time": 1.0}
TWO_TEAMS: dict[str, Any] = {  # each carrier drives north before its rovers can reach their tasks
    "name": "twoteams_map",
    "origin": ORIGIN,
    "carriers": [
        {"id": "c1", "sysid": 1, "position": [0, 0], **CARRIER, "fleet": {"count": 2, "sysid_start": 11}},
        {"id": "c2", "sysid": 2, "position": [90, 0], **CARRIER, "fleet": {"count": 2, "sysid_start": 31}},
    ],
    "rovers": {"max_speed": 4.0, "accel": None, "deploy_range": 30.0, "endurance_range": 600.0,
               "reserve": 0.1},
    "tasks": [{"id": "t1", "position": [-10, 70, 5]}, {"id": "t2", "position": [10, 80, 4]},
              {"id": "t3", "position": [80, 75, 5]}, {"id": "t4", "position": [100, 70, 4]}],
    "sim": {"speedup": 4.0, "faults": []},
    "links": {"heartbeat_timeout": 3.0},
}


def mission_dict(rovers: int = 2, speedup: float = 2.0) -> dict[str, Any]:
    d = copy.deepcopy(BASE)
    d["rovers"]["fleet"]["count"] = rovers
    d["sim"]["speedup"] = speedup
    return d


def write_mission(d: dict[str, Any], path: Path) -> Path:
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    return path


def mission(tmp_path: Path, rovers: int = 2) -> Mission:
    return load_mission(write_mission(mission_dict(rovers), tmp_path / "mission.yaml"))


class FakeClock:
    """A mission clock the test moves by hand."""

    def __init__(self, t: float = 0.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


def state_of(m: Mission, clock: FakeClock) -> FleetState:
    st = FleetState(m)
    st.mission_clock = clock
    return st


def deploy_plan(legs: list[tuple[str, str, list[float], list[float], float]], makespan: float,
                stop: list[float] | None = None) -> dict[str, Any]:
    """A one-stop deploy plan JSON: legs (rover, task, from, target, arrive)."""
    stop = stop or [0.0, 0.0, 0.0]
    return {"schema": "fleetctl.plan/1", "kind": "deploy", "planner": "lee",
            "carrier": {"start": [0, 0, 0], "heading": 0.0}, "makespan": makespan,
            "stops": [{"position": stop, "arrive": 0.0, "depart": 1.0,
                       "rovers": [{"rover": r, "task": t, "target": tgt, "path": [frm, tgt], "arrive": a}
                                  for r, t, frm, tgt, a in legs]}]}


def position_msg(sysid: int, e: float, n: float, u: float, vx: float = 0.0, vy: float = 0.0) -> bytes:
    from pymavlink.dialects.v20 import common

    mav = common.MAVLink(None, srcSystem=sysid, srcComponent=1)
    lat, lon, alt = enu_to_geodetic(e, n, u, Origin(ORIGIN["lat"], ORIGIN["lon"], ORIGIN["alt"]))
    msg = mav.global_position_int_encode(0, int(lat * 1e7), int(lon * 1e7), int((alt) * 1000),
                                         int(u * 1000), int(vx * 100), int(vy * 100), 0, 0)
    return bytes(msg.pack(mav))


def write_run(d: Path, t0: float = 1_000_000.0, speedup: float = 2.0, sim: bool = True) -> Path:
    """A run folder of a one-rover deployment: r1 launched at stop 1 flies to t1 at (20, 10, 5).

    Wall times: run at t0, plan +0.5, carrier started +1, stop reached +2, launched +2.5, reached +7.5,
    summary +8; telemetry of r1 every 0.5 s from +2.5 to +7.5 along the straight line."""
    d.mkdir(parents=True, exist_ok=True)
    write_mission(mission_dict(rovers=2), d / "mission.yaml")
    plan = deploy_plan([("r1", "t1", [0, 0, 0], [20, 10, 5], 6.0)], 6.0)
    recs = [
        {"t": t0, "elapsed": 0.0, "kind": "run", "mission": "viewtest", "command": "deploy",
         "speedup": speedup, "sim": sim},
        {"t": t0 + 0.2, "elapsed": 0.2, "kind": "phase", "phase": "deploy"},
        {"t": t0 + 0.5, "elapsed": 0.5, "kind": "plan", "plan": plan},
        {"t": t0 + 1.0, "elapsed": 1.0, "kind": "carrier_started", "vehicle": "carrier",
         "text": "carrier: route started (1 stops)"},
        {"t": t0 + 2.0, "elapsed": 2.0, "kind": "stop_reached", "vehicle": "carrier", "stop": 1,
         "text": "carrier: stop 1/1 reached"},
        {"t": t0 + 2.5, "elapsed": 2.5, "kind": "rover_launched", "vehicle": "r1", "task": "t1", "stop": 1,
         "text": "r1: launched for t1 at stop 1"},
        {"t": t0 + 7.5, "elapsed": 7.5, "kind": "task_reached", "vehicle": "r1", "task": "t1",
         "text": "r1: reached t1"},
        {"t": t0 + 8.0, "elapsed": 8.0, "kind": "summary", "result": "complete"},
    ]
    (d / "journal.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs), encoding="utf-8")
    out = bytearray()
    out += tlog_record(t0 + 0.1, position_msg(1, 0, 0, 0))
    out += tlog_record(t0 + 0.3, position_msg(11, 0, 0, 0))  # on the deck
    for k in range(11):
        f = k / 10
        vx = 4.0 if 0 < k < 10 else 0.0
        out += tlog_record(t0 + 2.5 + 0.5 * k, position_msg(11, 20 * f, 10 * f, 5 * f, vx))
    (d / "traffic.tlog").write_bytes(bytes(out))
    return d
