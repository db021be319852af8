"""Vehicles on several MAVLink links: system ids unique per link, not per mission; a vehicle's
link is its connection (``sim``: a simulated link of its own), a rover without one shares its
carrier's."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from fleetctl.mission import MissionError, load_mission
from fleetctl.mission.links import several_links, vehicle_links

ROOT = Path(__file__).resolve().parents[2]
ROVERS = {"max_speed": 5.0, "deploy_range": 40.0}
TASKS = [{"id": f"t{k}", "position": [10 * k, 20, 3]} for k in range(1, 5)]
A, B = "udpin://0.0.0.0:14550", "udpin://0.0.0.0:14551"


def carrier(cid: str, connection: str, x: float, **kv: Any) -> dict[str, Any]:
    """A carriers[i] entry; a keyword set to None leaves that key out."""
    d = {"id": cid, "sysid": 1, "connection": connection, "position": [x, 0], "max_speed": 10.0,
         "fleet": {"count": 2, "sysid_start": 11}, **kv}
    return {k: v for k, v in d.items() if v is not None}


def load(tmp_path: Path, data: dict[str, Any]) -> Any:
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return load_mission(path)


def teams(*carriers: dict[str, Any]) -> dict[str, Any]:
    return {"carriers": list(carriers), "rovers": copy.deepcopy(ROVERS), "tasks": copy.deepcopy(TASKS)}


def test_simulated_carriers_reuse_system_ids(tmp_path: Path) -> None:
    m = load(tmp_path, teams(carrier("c1", "sim", 0), carrier("c2", "sim", 80)))
    links = vehicle_links(m)
    assert links == {"c1": "sim:c1", "r1": "sim:c1", "r2": "sim:c1", "c2": "sim:c2", "r3": "sim:c2",
                     "r4": "sim:c2"}
    assert [u.sysid for u in m.rovers.units] == [11, 12, 11, 12] and several_links(m)


def test_real_links_reuse_system_ids(tmp_path: Path) -> None:
    m = load(tmp_path, teams(carrier("c1", A, 0), carrier("c2", B, 80)))
    assert {vid: link for vid, link in vehicle_links(m).items() if vid.startswith("c")} == {"c1": A, "c2": B}


def test_one_link_refuses_a_repeated_sysid(tmp_path: Path) -> None:
    with pytest.raises(MissionError) as err:
        load(tmp_path, teams(carrier("c1", A, 0), carrier("c2", A, 80)))
    msg = str(err.value)
    assert "carriers[1].sysid: duplicate vehicle sysid 1 (also at carriers[0].sysid)" in msg
    assert "on one link unique" in msg


def test_the_message_names_the_link_when_there_are_several(tmp_path: Path) -> None:
    units = [{"id": "x1", "sysid": 5, "connection": B}, {"id": "x2", "sysid": 5, "connection": B}]
    with pytest.raises(MissionError) as err:
        load(tmp_path, teams(carrier("c1", A, 0), carrier("c2", A, 80, sysid=2, fleet=None, units=units)))
    assert f"carriers[1].units[1].sysid: duplicate vehicle sysid 5 on {B} " in str(err.value)


def test_a_rover_on_its_own_link_reuses_a_sysid(tmp_path: Path) -> None:
    data = {"carrier": {"sysid": 1, "connection": A, "position": [0, 0], "max_speed": 10.0},
            "rovers": {**ROVERS, "units": [{"id": "r1", "sysid": 11},
                                           {"id": "r2", "sysid": 11, "connection": B}]},
            "tasks": TASKS[:2]}
    m = load(tmp_path, data)
    assert vehicle_links(m) == {"carrier": A, "r1": A, "r2": B}
    data["rovers"]["units"][1].pop("connection")
    with pytest.raises(MissionError, match=r"rovers.units\[1\].sysid: duplicate vehicle sysid 11"):
        load(tmp_path, data)


def test_shipped_missions_keep_their_links_and_sysids() -> None:
    m = load_mission(ROOT / "missions" / "two_carriers.yaml")
    assert [u.sysid for u in m.rovers.units] == [*range(11, 19), *range(31, 39)]
    assert set(vehicle_links(m).values()) == {"sim:c1", "sim:c2"}
    one = load_mission(ROOT / "missions" / "recon.yaml")
    assert not several_links(one)


def test_four_carriers_of_a_hundred_rovers(tmp_path: Path) -> None:
    """404 vehicles on four links; rovers numbered on from the previous carrier's would pass 255,
    and the message says how to number them afresh on a carrier's own link."""
    cars = [carrier(f"c{k + 1}", f"udpin://0.0.0.0:{14550 + k}", 300.0 * k, fleet={"count": 100})
            for k in range(4)]
    with pytest.raises(MissionError) as err:
        load(tmp_path, teams(*cars))
    msg = str(err.value)
    assert "carriers[2].fleet.sysid_start: rover sysids 211..310 exceed 255" in msg
    assert "'sysid_start: 2' numbers its rovers afresh" in msg
    for c in cars:
        c["fleet"]["sysid_start"] = 2
    m = load(tmp_path, teams(*cars))
    links = vehicle_links(m)
    assert len(links) == 404 and len(set(links.values())) == 4
    assert {u.sysid for u in m.rovers.units} == set(range(2, 102))
