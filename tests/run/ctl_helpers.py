"""Helpers for the controller tests: mission files for a small simulated fleet, and the fleet."""

from __future__ import annotations

import contextlib
import copy
import socket
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import yaml

from fleetctl.geo import Origin, local_to_geodetic
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.mission import Mission, load_mission
from sitl import FleetConfig, SimFleet

ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}

BASE: dict[str, Any] = {
    "name": "ctltest",
    "origin": ORIGIN,
    "carrier": {"id": "carrier", "connection": "sim", "sysid": 1, "position": [0, 0], "heading_deg": 0,
                "max_speed": 10.0, "accel": 5.0, "turn_rate": None, "unload_time": 1.0, "load_time": 1.0},
    "rovers": {"max_speed": 5.0, "accel": None, "deploy_range": 40.0, "endurance_range": 600.0,
               "reserve": 0.1, "fleet": {"count": 2, "sysid_start": 11}},
    "tasks": [{"id": "t1", "position": [20, 10, 5]}, {"id": "t2", "position": [40, -10, 4]}],
    "sim": {"speedup": 20.0, "faults": []},
    "links": {"heartbeat_timeout": 3.0},
}


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def mission_dict(*, rovers: int = 2, carrier_connection: str = "sim", units: list[dict] | None = None,
                 faults: list[dict] | None = None, heartbeat_timeout: float = 3.0,
                 speedup: float = 20.0) -> dict[str, Any]:
    d = copy.deepcopy(BASE)
    d["carrier"]["connection"] = carrier_connection
    if units is not None:
        del d["rovers"]["fleet"]
        d["rovers"]["units"] = units
    else:
        d["rovers"]["fleet"]["count"] = rovers
    d["tasks"] = d["tasks"][: max(1, min(rovers if units is None else len(units), 2))]
    d["sim"] = {"speedup": speedup, "faults": faults or []}
    d["links"] = {"heartbeat_timeout": heartbeat_timeout}
    return d


def write_mission(d: dict[str, Any], path: Path) -> Path:
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    return path


def mission_from(d: dict[str, Any], tmp_path: Path, name: str = "mission.yaml") -> Mission:
    return load_mission(write_mission(d, tmp_path / name))


@contextlib.asynccontextmanager
async def sim_fleet(d: dict[str, Any], autopilot: str | None = None) -> AsyncIterator[SimFleet]:
    config = FleetConfig.from_mission_dict(d, autopilot=autopilot)
    async with SimFleet(config) as fleet:
        yield fleet
    assert fleet.errors == 0, fleet.last_error


def apply_positions(v: Vehicle, origin: Origin, track: list[tuple[float, float, float, float]]) -> None:
    """Apply GLOBAL_POSITION_INT reports to ``v`` (never connected): each (vehicle s, east m from
    ``origin``, velocity estimate east m/s, up m/s)."""
    import time

    from pymavlink.dialects.v20 import ardupilotmega as M
    for t, x, ve, vu in track:
        lat, lon, _ = local_to_geodetic(x, 0.0, 0.0, origin)
        msg = M.MAVLink_global_position_int_message(round(t * 1000), round(lat * 1e7), round(lon * 1e7),
                                                    round(origin.alt * 1000), 0, 0, round(ve * 100),
                                                    round(-vu * 100), 0xFFFF)
        v._apply_position(msg, time.monotonic())
