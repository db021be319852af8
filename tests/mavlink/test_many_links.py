"""More than 255 vehicles in one controller: four carriers on simulated links of their own, each
with 64 rovers, every link numbering its vehicles with the same system ids (carrier 1, rovers
2..65). Every vehicle proxy connects to its own simulated vehicle and shows that vehicle's position,
never the one of its namesake on another link."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import yaml

from fleetctl.mavlink.fleet import connect_fleet
from fleetctl.mission import load_mission
from fleetctl.run.sim import sim_fleet_config
from sitl import SimFleet

CARRIERS, ROVERS, SPACING = 4, 64, 300.0


def mission_file(tmp_path: Path) -> Path:
    carriers = [{"id": f"c{k + 1}", "sysid": 1, "connection": "sim", "position": [k * SPACING, 0.0],
                 "max_speed": 10.0, "fleet": {"count": ROVERS, "sysid_start": 2}} for k in range(CARRIERS)]
    d = {"name": "many", "origin": {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}, "carriers": carriers,
         "rovers": {"max_speed": 5.0, "deploy_range": 40.0},
         "tasks": [{"id": f"t{k}", "position": [k * SPACING, 20.0, 3.0]} for k in range(CARRIERS)]}
    path = tmp_path / "many.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


async def test_every_vehicle_of_four_links_is_its_own(tmp_path: Path) -> None:
    mission = load_mission(mission_file(tmp_path))
    config = dataclasses.replace(sim_fleet_config(mission), position_hz=1.0)
    async with SimFleet(config) as sim:
        fleet = await connect_fleet(mission, sim.endpoints, timeout=30.0, configure_streams=False)
        async with fleet:
            assert len(fleet.vehicles) == CARRIERS * (ROVERS + 1) > 255
            assert len(fleet.links) == CARRIERS
            addresses = {(fleet.urls[vid], v.sysid) for vid, v in fleet.vehicles.items()}
            assert len(addresses) == len(fleet.vehicles)  # a link and a system id: one vehicle
            assert {v.sysid for v in fleet.vehicles.values()} == set(range(1, ROVERS + 2))
            await sim.wait_for(lambda: all(v.enu is not None for v in fleet.vehicles.values()), timeout=30.0)
            for vid, v in fleet.vehicles.items():
                own = sim.body(vid).position
                assert v.enu is not None and math.dist(v.enu[:2], own[:2]) < 1.0, (vid, v.enu, own)
            assert sum(link.route_conflicts for link in fleet.links.values()) == 0
