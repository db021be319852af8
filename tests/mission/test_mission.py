"""fleetctl.mission: the mission-file contract (docs/mission-file.md), one test per rejection rule."""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import pytest
import yaml

from fleetctl.geo import Origin, compass_to_math, enu_to_geodetic
from fleetctl.mission import Mission, MissionError, load_mission, parse_mission
from fleetctl.mission.flight import (
    LAND_SETTLE,
    MEET_HEIGHT,
    TAKEOFF_HEIGHT,
    TAKEOFF_SETTLE,
    default_land_time,
    default_takeoff_time,
)
from planners.core.problem import CarrierSpec, CollectProblem, DeployProblem, Motion, Task

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}

BASE: dict[str, Any] = {
    "name": "t",
    "carrier": {"position": [0, 0], "max_speed": 15.0},
    "rovers": {"max_speed": 1.0, "deploy_range": 25.0},
    "tasks": [{"id": "a", "position": [10, 20, 4]}, {"id": "b", "position": [40, 10]}],
}


def load(tmp_path: Path, data: Any = None, **changes: Any) -> Mission:
    """Write ``data`` (default: BASE with top-level ``changes``) as YAML and load it."""
    if data is None:
        data = copy.deepcopy(BASE)
        data.update(changes)
    f = tmp_path / "m.yaml"
    f.write_text(data if isinstance(data, str) else yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return load_mission(f)


def error(tmp_path: Path, data: Any = None, **changes: Any) -> str:
    with pytest.raises(MissionError) as info:
        load(tmp_path, data, **changes)
    msg = str(info.value)
    assert msg.startswith(str(tmp_path / "m.yaml")), msg  # always names the file
    assert "Traceback" not in msg and msg.count("\n") <= 1
    return msg


def with_(section: str, **kv: Any) -> dict[str, Any]:
    """BASE with keys of one section replaced (value None deletes the key)."""
    data = copy.deepcopy(BASE)
    sec = data.setdefault(section, {})
    for k, v in kv.items():
        if v is None:
            sec.pop(k, None)
        else:
            sec[k] = v
    return data


# ------------------------------------------------------------------------------------ accepted


def mission_files() -> list[Path]:
    return sorted(MISSIONS.glob("**/*.yaml"))


def test_mission_directory_is_populated() -> None:
    names = {p.relative_to(MISSIONS).as_posix() for p in mission_files()}
    assert {"recon.yaml", "paper/deploy_2tasks.yaml", "paper/deploy_2tasks_3d.yaml"} <= names
    assert {f"paper/deploy_15tasks_d{d}.yaml" for d in (25, 20, 15, 10)} <= names
    assert {f"paper/deploy_6tasks_3d_d{d}.yaml" for d in (7, 15, 25)} <= names


@pytest.mark.parametrize("path", mission_files(), ids=lambda p: p.relative_to(MISSIONS).as_posix())
def test_every_mission_file_loads(path: Path) -> None:
    m = load_mission(path)
    assert m.path == path
    if m.operation:  # a long operation: fewer rovers than tasks, each task with its work
        ops = m.operation_problem()
        assert len(ops.tasks) == len(m.tasks) > len(ops.rovers) > 0
    elif m.tasks:
        problem = m.deploy_problem()
        assert len(problem.rovers) >= len(problem.tasks) > 0
    else:  # a collection-only scenario
        with pytest.raises(MissionError, match="no tasks"):
            m.deploy_problem()
    if m.collection is not None:
        assert m.collect_problem().rovers == m.collection


@pytest.mark.parametrize("path", sorted(MISSIONS.glob("paper/deploy_*.yaml")), ids=lambda p: p.name)
def test_paper_missions_cite_their_table_and_use_exactly_enough_rovers(path: Path) -> None:
    header = path.read_text(encoding="utf-8").split("\nname:")[0]
    assert "Table 4." in header and "Reported result" in header
    m = load_mission(path)
    assert len(m.rovers.units) == len(m.tasks)
    assert m.rovers.accel is None and m.carrier.heading_deg == 0.0


def test_paper_parameters_match_the_dissertation() -> None:
    m = load_mission(MISSIONS / "paper/deploy_15tasks_d25.yaml")
    assert m.carrier.spec() == CarrierSpec(15.0, 10.0, 3.0, 4.0, 0.0)
    assert m.rovers.max_speed == 1.0 and m.rovers.deploy_range == 25.0
    assert m.carrier.position == (52.0, 60.0) and len(m.tasks) == 15
    assert m.tasks[11] == Task("t12", (92.0, 93.0, 0.0))
    assert "47.02" in (MISSIONS / "paper/deploy_15tasks_d25.yaml").read_text()
    six = load_mission(MISSIONS / "paper/deploy_6tasks_3d_d7.yaml")
    assert [t.position for t in six.tasks][3] == (13.0, 75.0, 7.0) and six.rovers.deploy_range == 7.0
    assert "52.95" in (MISSIONS / "paper/deploy_6tasks_3d_d7.yaml").read_text()


def test_recon_mission() -> None:
    m = load_mission(MISSIONS / "recon.yaml")
    assert 12 <= len(m.tasks) <= 20
    assert m.carrier.connection == "sim"
    assert m.origin == Origin(47.397742, 8.545594, 488.0)
    assert m.obstacles == ()
    assert any(t.position[2] > 0 for t in m.tasks)
    geodetic = [t for t in m.raw["tasks"] if "lat" in t]
    assert 1 <= len(geodetic) <= 2
    t15 = next(t for t in m.tasks if t.id == "t15")
    assert t15.position == pytest.approx((150.0, 110.0, 15.0), abs=1.0)


def test_defaults(tmp_path: Path) -> None:
    m = load(tmp_path)
    c = m.carrier
    assert (c.id, c.connection, c.sysid, c.heading_deg) == ("carrier", "sim", 1, 0.0)
    assert (c.accel, c.turn_rate, c.unload_time, c.load_time) == (None, None, 0.0, 0.0)
    r = m.rovers
    # no endurance_range: a 10-minute battery at cruise speed (at least twice the deploy range)
    assert (r.accel, r.reserve, r.energy, r.endurance_range) == (None, 0.1, None, 600.0 * r.max_speed)
    assert [(u.id, u.sysid, u.connection) for u in r.units] == [("r1", 11, None), ("r2", 12, None)]
    assert m.links.heartbeat_timeout == 3.0
    assert (m.planner.deploy, m.planner.collect, m.planner.seed, m.planner.roadmap) == ("lee", "lee", 0, None)
    assert m.dwell == 60.0 and m.sim.speedup == 1.0 and m.sim.faults == ()
    assert m.origin is None and m.bounds is None and m.collection is None and m.mqtt is None
    assert m.tasks[1].position == (40.0, 10.0, 0.0)
    assert m.raw == BASE


def test_name_defaults_to_file_stem(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    del data["name"]
    assert load(tmp_path, data).name == "m"


def test_fleet_sysids_follow_the_carrier(tmp_path: Path) -> None:
    data = with_("carrier", sysid=5)
    data["rovers"]["fleet"] = {"count": 3}
    m = load(tmp_path, data)
    assert [u.sysid for u in m.rovers.units] == [15, 16, 17] and m.rovers.ids == ("r1", "r2", "r3")


# the mission-file contract's example mission (one comment shortened for the line length)
DESIGN_EXAMPLE = """\
name: recon
origin: {lat: 47.397742, lon: 8.545594, alt: 488.0}
carrier:
  id: carrier
  connection: sim            # sim | udp://HOST:PORT | udpin://HOST:PORT | tcp://HOST:PORT | serial:///dev/ttyACM0?baud=57600
  sysid: 1
  position: [52, 60]         # ENU metres; start for planning/sim (live runs read telemetry)
  heading_deg: 0
  max_speed: 15.0
  accel: 10.0                # null = constant speed
  turn_rate: 3.0             # rad/s, null = instantaneous
  unload_time: 4.0
  load_time: 4.0
rovers:
  max_speed: 1.0
  accel: null
  deploy_range: 25.0         # d_deploy (m); or give energy terms and derive it (eq. in ch. 3.2)
  endurance_range: 60.0      # metres of flight on a full battery (collection radius model)
  reserve: 0.1               # fraction of battery never planned away
  fleet: {count: 16, sysid_start: 11}   # r1..r16, sysids 11..26; or units: [...]
tasks:
  - {id: t1, position: [57, 11, 4]}      # ENU metres, z = height of the task above ground
  - {id: t2, lat: 47.3981, lon: 8.5461, alt: 495.0}
obstacles:                                # optional ground polygons (ENU metres)
  - [[20, 20], [30, 20], [30, 40], [20, 40]]
bounds: [[0, 0], [100, 100]]              # workspace for roadmap sampling (needed with obstacles)
collection:                               # optional: offline collection problem for `fleetctl plan --collect`
  rovers: [{id: r1, position: [57, 11, 8], range: 20.0}]
sim:                                      # the embedded simulated fleet (used when connection: sim)
  speedup: 1.0                            # simulated seconds per wall second
  faults:                                 # no vehicle = every vehicle; times are simulated seconds
    - {vehicle: r3, kind: dropout, at: 20.0, until: 45.0}   # until omitted = never back
    - {kind: packet_loss, rate: 0.2}
    - {kind: latency, seconds: 0.2}
    - {vehicle: r2, kind: battery_drain, factor: 2.0}
    - {vehicle: r5, kind: refuse_arm}
links: {heartbeat_timeout: 3.0}
planner: {deploy: lee, collect: lee, seed: 0}   # defaults; roadmap parameters join with ch. 6
dwell: 60.0                               # seconds on task before collection (`fleetctl run`)
mqtt: {url: "mqtt://127.0.0.1:1883", topic_prefix: fleetctl/recon}   # optional fleet bus
"""


def test_full_contract_example_from_design(tmp_path: Path) -> None:
    m = load(tmp_path, DESIGN_EXAMPLE)
    assert len(m.rovers.units) == 16 and m.rovers.units[-1].sysid == 26
    assert [f.kind for f in m.sim.faults] == [
        "dropout",
        "packet_loss",
        "latency",
        "battery_drain",
        "refuse_arm",
    ]
    assert m.sim.faults[0].until == 45.0 and m.sim.faults[1].rate == 0.2 and m.sim.faults[1].vehicle is None
    assert m.mqtt is not None and m.mqtt.topic_prefix == "fleetctl/recon"
    assert m.bounds == ((0.0, 0.0), (100.0, 100.0)) and len(m.obstacles) == 1


def test_optional_sections(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["rovers"]["units"] = [{"id": "alpha", "sysid": 20}, {"id": "beta", "sysid": 21}]
    data["carrier"]["connection"] = "udpin://0.0.0.0:14550"
    data["rovers"]["units"][1]["connection"] = "serial:///dev/ttyUSB0?baud=57600"
    data["planner"] = {"deploy": "greedy2opt", "seed": 7, "roadmap": {"xi1": 1.5, "xi2": 150, "phi": 0.15}}
    data["mqtt"] = {
        "url": "mqtts://broker.local:8883",
        "client_id": "c",
        "username": "u",
        "password_env": "FLEET_PW",
        "tls": {"ca": "ca.pem", "cert": "c.pem", "key": "k.pem"},
    }
    data["sim"] = {"speedup": 10, "faults": [{"vehicle": "beta", "kind": "dropout", "at": 5, "until": 9}]}
    m = load(tmp_path, data)
    assert m.rovers.ids == ("alpha", "beta") and m.rovers.units[0].connection is None
    assert m.planner.roadmap is not None and m.planner.roadmap.xi2 == 150.0 and m.planner.roadmap.xi3 is None
    assert m.mqtt is not None and m.mqtt.topic_prefix == "fleetctl/t" and m.mqtt.tls is not None
    assert m.deploy_problem().rovers == ("alpha", "beta")
    assert m.sim.speedup == 10.0 and m.sim.faults[0].vehicle == "beta"


def test_planner_budget_reaches_both_problems(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["planner"] = {"budget_ms": 250}
    m = load(tmp_path, data)
    assert m.planner.budget_ms == 250.0 and m.deploy_problem().budget_ms == 250.0
    assert load(tmp_path, copy.deepcopy(BASE)).deploy_problem().budget_ms is None  # quick plan by default
    data["planner"] = {"budget_ms": -1}
    with pytest.raises(MissionError, match="budget_ms"):
        load(tmp_path, data)


@pytest.mark.parametrize(
    "url",
    [
        "sim",
        "udp://127.0.0.1:14550",
        "udpout://10.0.0.2:14555",
        "udpin://0.0.0.0:14550",
        "tcp://localhost:5760",
        "serial:///dev/ttyACM0?baud=57600",
    ],
)
def test_valid_connections(tmp_path: Path, url: str) -> None:
    assert load(tmp_path, with_("carrier", connection=url)).carrier.connection == url


def test_lat_lon_tasks_are_converted(tmp_path: Path) -> None:
    origin = Origin(**ORIGIN)
    lat, lon, _ = enu_to_geodetic(120.0, -80.0, 0.0, origin)
    data = copy.deepcopy(BASE)
    data["origin"] = ORIGIN
    data["tasks"] = [
        {"id": "a", "lat": lat, "lon": lon, "alt": origin.alt + 6.0},
        {"id": "b", "lat": ORIGIN["lat"], "lon": ORIGIN["lon"]},  # alt omitted: on the ground
    ]
    m = load(tmp_path, data)
    assert m.tasks[0].position == pytest.approx((120.0, -80.0, 6.0), abs=2e-3)
    assert m.tasks[1].position == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


def test_energy_derived_deploy_range(tmp_path: Path) -> None:
    data = with_("rovers", deploy_range=None, energy={"initial": 100.0, "task": 20.0, "rho": 0.5})
    m = load(tmp_path, data)
    assert m.rovers.deploy_range == pytest.approx(0.5 * (100.0 - 20.0) / 2)  # 20 m
    assert m.rovers.endurance_range == pytest.approx(50.0)  # rho * initial
    assert m.deploy_problem().deploy_range == pytest.approx(20.0)


def test_deploy_problem(tmp_path: Path) -> None:
    data = with_(
        "carrier", position=[5, 6], heading_deg=90, accel=2.0, turn_rate=1.5, unload_time=3, load_time=2
    )
    data["rovers"]["accel"] = 4.0
    p = load(tmp_path, data).deploy_problem()
    assert isinstance(p, DeployProblem)
    # the time model's take-off and touch-down times default to fleetctl.mission.flight's
    times = default_takeoff_time(1.0, 4.0), default_land_time(1.0)
    assert p.carrier == CarrierSpec(15.0, 2.0, 1.5, 3.0, 2.0, *times, vertex_stops=True)
    assert p.rover == Motion(1.0, 4.0) and p.deploy_range == 25.0
    assert p.start == (5.0, 6.0, 0.0) and p.heading == pytest.approx(compass_to_math(90)) == pytest.approx(
        0.0
    )
    assert p.tasks == (Task("a", (10.0, 20.0, 4.0)), Task("b", (40.0, 10.0, 0.0)))
    assert p.rovers == ("r1", "r2")


def test_takeoff_and_land_times_from_the_vertical_speeds_or_given(tmp_path: Path) -> None:
    data = with_("rovers", climb_rate=2.0, land_speed=0.5)
    r = load(tmp_path, data).rovers
    assert r.takeoff_time == pytest.approx(TAKEOFF_HEIGHT / 2.0 + TAKEOFF_SETTLE)
    assert r.land_time == pytest.approx(MEET_HEIGHT / 0.5 + LAND_SETTLE)
    deck = with_("rovers", climb_rate=2.0, land_speed=0.5)
    deck["carrier"]["deck_height"] = 0.5  # the descent onto a deck 0.5 m up: 2.5 m
    assert load(tmp_path, deck).rovers.land_time == pytest.approx((MEET_HEIGHT - 0.5) / 0.5 + LAND_SETTLE)
    data = with_("rovers", takeoff_time=0, land_time=2.5)
    m = load(tmp_path, data)
    assert (m.rovers.takeoff_time, m.rovers.land_time) == (0.0, 2.5)
    assert m.deploy_problem().carrier.deploy_stop_time == pytest.approx(m.carrier.unload_time)
    for bad in ({"land_time": -1}, {"takeoff_time": "soon"}, {"climb_rate": 0}):
        with pytest.raises(MissionError, match="rovers"):
            load(tmp_path, with_("rovers", **bad))


def test_collect_problem(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["collection"] = {
        "rovers": [
            {"id": "r2", "position": [57, 11, 8], "range": 20.0},
            {"id": "r1", "position": [3, 4], "range": 12},
        ]
    }
    p = load(tmp_path, data).collect_problem()
    assert isinstance(p, CollectProblem)
    assert [(r.id, r.position, r.range) for r in p.rovers] == [
        ("r2", (57.0, 11.0, 8.0), 20.0),
        ("r1", (3.0, 4.0, 0.0), 12.0),
    ]
    assert p.heading == pytest.approx(math.pi / 2) and p.start == (0.0, 0.0, 0.0)


def test_collect_problem_without_collection_section(tmp_path: Path) -> None:
    with pytest.raises(MissionError, match="collection"):
        load(tmp_path).collect_problem()


def test_parse_mission_from_a_dict_names_the_source() -> None:
    m = parse_mission(copy.deepcopy(BASE), "inline")
    assert m.path is None and len(m.tasks) == 2
    bad = with_("rovers", max_speed=-1)
    with pytest.raises(MissionError, match=r"^inline: rovers\.max_speed: "):
        parse_mission(bad, "inline")


# ------------------------------------------------------------------------------------ rejected


def test_unknown_key_suggests_the_closest(tmp_path: Path) -> None:
    msg = error(tmp_path, with_("rovers", max_sped=1.0))
    assert "rovers.max_sped" in msg and "unknown key" in msg
    assert "did you mean 'max_speed'" in msg and "deploy_range" in msg  # lists the allowed keys


def test_unknown_top_level_key(tmp_path: Path) -> None:
    msg = error(tmp_path, obstacle=[])
    assert ": obstacle: unknown key; did you mean 'obstacles'?" in msg


def test_unknown_key_in_a_list_item(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["tasks"][1]["heigth"] = 3
    assert "tasks[1].heigth: unknown key" in error(tmp_path, data)


@pytest.mark.parametrize(
    ("section", "key", "value", "got"),
    [
        ("carrier", "max_speed", True, "boolean"),
        ("rovers", "deploy_range", "25", "string"),
        ("carrier", "position", [1, False], "boolean"),
        ("carrier", "sysid", 2.5, "number"),
        ("rovers", "reserve", [0.1], "list"),
        ("carrier", "id", 7, "number"),
    ],
)
def test_wrong_type(tmp_path: Path, section: str, key: str, value: Any, got: str) -> None:
    msg = error(tmp_path, with_(section, **{key: value}))
    assert f"{section}.{key}" in msg and "expected" in msg and got in msg


def test_bool_is_not_a_number(tmp_path: Path) -> None:
    msg = error(tmp_path, with_("carrier", turn_rate=True))
    assert "carrier.turn_rate" in msg and "got a boolean (true)" in msg


def test_section_of_the_wrong_type(tmp_path: Path) -> None:
    msg = error(tmp_path, rovers=[1, 2])
    assert ": rovers: expected a mapping" in msg


@pytest.mark.parametrize(
    ("section", "key", "value"),
    [
        ("rovers", "max_speed", 0),
        ("rovers", "max_speed", -1.0),
        ("carrier", "max_speed", -15),
        ("rovers", "deploy_range", 0.0),
        ("rovers", "endurance_range", -5),
        ("carrier", "accel", 0),
        ("rovers", "accel", -2),
        ("carrier", "turn_rate", 0),
        ("carrier", "unload_time", -1),
        ("carrier", "load_time", -0.5),
        ("links", "heartbeat_timeout", 0),
    ],
)
def test_non_positive_values(tmp_path: Path, section: str, key: str, value: float) -> None:
    msg = error(tmp_path, with_(section, **{key: value}))
    assert f"{section}.{key}" in msg and "out of range" in msg and (">" in msg)


def test_negative_times(tmp_path: Path) -> None:
    assert "dwell: -3 is out of range; set it to a number >= 0" in error(tmp_path, dwell=-3)
    msg = error(tmp_path, sim={"faults": [{"kind": "dropout", "at": -1}]})
    assert "sim.faults[0].at" in msg and ">= 0" in msg


def test_fewer_rovers_than_tasks(tmp_path: Path) -> None:
    msg = error(tmp_path, with_("rovers", fleet={"count": 1}))
    assert "rovers.fleet.count" in msg and "only 1 rover(s) for 2 tasks" in msg and "at least 2" in msg
    units = with_("rovers", units=[{"id": "x", "sysid": 20}])
    assert "rovers.units: only 1 rover(s) for 2 tasks" in error(tmp_path, units)


def test_task_higher_than_deploy_range(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["tasks"][1]["position"] = [40, 10, 25.5]
    msg = error(tmp_path, data)
    assert "tasks[1]" in msg and "'b' is 25.5 m high" in msg and "deploy_range 25" in msg
    data["tasks"][1]["position"] = [40, 10, 25.0]  # exactly at the range: reachable from below
    assert load(tmp_path, data).tasks[1].position[2] == 25.0


def test_task_higher_than_energy_derived_deploy_range(tmp_path: Path) -> None:
    data = with_("rovers", deploy_range=None, energy={"initial": 10, "task": 3, "rho": 1})  # 3.5 m
    assert "tasks[0]" in error(tmp_path, data)


def test_negative_task_height(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["tasks"][0]["position"] = [1, 2, -3]
    msg = error(tmp_path, data)
    assert "tasks[0]" in msg and "negative height" in msg


def test_duplicate_task_ids(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["tasks"][1]["id"] = "a"
    msg = error(tmp_path, data)
    assert "tasks[1].id" in msg and "duplicate task id 'a'" in msg and "tasks[0].id" in msg


def test_duplicate_rover_ids(tmp_path: Path) -> None:
    data = with_("rovers", units=[{"id": "x", "sysid": 20}, {"id": "x", "sysid": 21}])
    msg = error(tmp_path, data)
    assert "rovers.units[1].id" in msg and "duplicate vehicle id 'x'" in msg


def test_rover_id_equal_to_carrier_id(tmp_path: Path) -> None:
    assert "duplicate vehicle id 'r1'" in error(tmp_path, with_("carrier", id="r1"))


def test_duplicate_sysids(tmp_path: Path) -> None:
    data = with_("rovers", units=[{"id": "x", "sysid": 20}, {"id": "y", "sysid": 20}])
    assert "rovers.units[1].sysid" in error(tmp_path, data)
    clash = with_("rovers", fleet={"sysid_start": 1})  # r1 would get the carrier's sysid 1
    msg = error(tmp_path, clash)
    assert "rovers.fleet.sysid_start" in msg and "duplicate vehicle sysid 1" in msg


def test_duplicate_collection_rovers(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["collection"] = {"rovers": [{"id": "r1", "position": [0, 0], "range": 5}] * 2}
    assert "collection.rovers[1].id" in error(tmp_path, data)


def test_duplicate_yaml_key(tmp_path: Path) -> None:
    text = yaml.safe_dump(BASE, sort_keys=False) + "name: again\n"
    msg = error(tmp_path, text)
    assert f":{len(text.splitlines())}: name: duplicate key" in msg, msg  # the line of the second one


def test_lat_lon_task_without_origin(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["tasks"][1] = {"id": "b", "lat": 47.398, "lon": 8.546, "alt": 490.0}
    msg = error(tmp_path, data)
    assert "tasks[1].lat" in msg and "origin" in msg


def test_task_with_both_position_and_lat_lon(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["origin"] = ORIGIN
    data["tasks"][0]["lat"] = 47.4
    assert "tasks[0].lat: give either 'position'" in error(tmp_path, data)


def test_task_without_position(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["tasks"][0] = {"id": "a"}
    assert "tasks[0].position: required key is missing" in error(tmp_path, data)


def test_malformed_yaml_reports_its_line(tmp_path: Path) -> None:
    text = "name: x\ncarrier:\n  position: [0, 0\n  max_speed: 3\nrovers: {}\n"
    msg = error(tmp_path, text)
    assert "malformed YAML" in msg and ":4:" in msg


def test_bad_indentation_reports_its_line(tmp_path: Path) -> None:
    text = "name: x\ncarrier:\n  position: [0, 0]\n max_speed: 3\n"
    msg = error(tmp_path, text)
    assert "malformed YAML" in msg and ":4:" in msg


def test_validation_errors_report_the_line(tmp_path: Path) -> None:
    text = yaml.safe_dump(with_("rovers", max_speed=-2), sort_keys=False)
    line = next(i for i, s in enumerate(text.splitlines(), 1) if "max_speed: -2" in s)
    assert f"m.yaml:{line}: rovers.max_speed:" in error(tmp_path, text)


def test_task_inside_an_obstacle(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["obstacles"] = [[[0, 30], [5, 30], [5, 35], [0, 35]], [[35, 5], [45, 5], [45, 15], [35, 15]]]
    data["bounds"] = [[-10, -10], [100, 100]]
    msg = error(tmp_path, data)
    assert "tasks[1]" in msg and "inside obstacles[1]" in msg


def test_carrier_start_inside_an_obstacle(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["obstacles"] = [[[-1, -1], [1, -1], [1, 1], [-1, 1]]]
    data["bounds"] = [[-10, -10], [100, 100]]
    assert "carrier.position" in error(tmp_path, data)


@pytest.mark.parametrize(
    ("polygon", "what"),
    [
        ([[0, 0], [10, 10], [10, 0], [0, 10]], "Self-intersection"),
        ([[0, 0], [1, 1]], "at least 3"),
        ([[0, 0], [1, 1], [2, 2]], "zero area"),
    ],
)
def test_invalid_obstacle_polygon(tmp_path: Path, polygon: list[list[float]], what: str) -> None:
    data = copy.deepcopy(BASE)
    data["obstacles"] = [[[50, 50], [60, 50], [60, 60]], polygon]
    data["bounds"] = [[-10, -10], [100, 100]]
    msg = error(tmp_path, data)
    assert "obstacles[1]" in msg and what in msg


def test_obstacles_without_bounds(tmp_path: Path) -> None:
    msg = error(tmp_path, obstacles=[[[50, 50], [60, 50], [60, 60]]])
    assert ": bounds: obstacles need a workspace" in msg


def test_task_outside_bounds(tmp_path: Path) -> None:
    msg = error(tmp_path, bounds=[[-5, -5], [30, 30]])
    assert "tasks[1]" in msg and "outside bounds" in msg


def test_malformed_bounds(tmp_path: Path) -> None:
    assert ": bounds: expected two corners" in error(tmp_path, bounds=[[10, 10], [0, 0]])


@pytest.mark.parametrize("sysid", [0, 256, -1])
def test_sysid_out_of_range(tmp_path: Path, sysid: int) -> None:
    msg = error(tmp_path, with_("carrier", sysid=sysid))
    assert "carrier.sysid" in msg and "1..255" in msg


def test_fleet_sysids_overflow(tmp_path: Path) -> None:
    msg = error(tmp_path, with_("rovers", fleet={"count": 10, "sysid_start": 250}))
    assert "rovers.fleet.sysid_start" in msg and "exceed 255" in msg


@pytest.mark.parametrize(
    ("path", "key"),
    [
        (("carrier",), "max_speed"),
        (("carrier",), "position"),
        (("rovers",), "max_speed"),
        ((), "rovers"),
        ((), "tasks"),
        ((), "carrier"),
    ],
)
def test_missing_required_key(tmp_path: Path, path: tuple[str, ...], key: str) -> None:
    data = copy.deepcopy(BASE)
    node = data
    for p in path:
        node = node[p]
    del node[key]
    msg = error(tmp_path, data)
    assert ".".join((*path, key)) + ": required key is missing" in msg


def test_empty_task_list(tmp_path: Path) -> None:
    msg = error(tmp_path, tasks=[])
    assert ": tasks: the task list is empty" in msg and "collection" in msg
    # allowed in a collection-only mission; the fleet then defaults to the collected rovers
    m = load(tmp_path, tasks=[], collection={"rovers": [{"id": "r1", "position": [1, 2, 3], "range": 9}]})
    assert m.tasks == () and m.rovers.ids == ("r1",)
    with pytest.raises(MissionError, match="no tasks"):
        m.deploy_problem()


def test_empty_file(tmp_path: Path) -> None:
    assert "the mission file is empty" in error(tmp_path, "# nothing\n")


def test_top_level_not_a_mapping(tmp_path: Path) -> None:
    assert "expected a mapping" in error(tmp_path, "- a\n- b\n")


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(MissionError, match="cannot read"):
        load_mission(tmp_path / "nope.yaml")


@pytest.mark.parametrize(
    "url",
    [
        "udp://127.0.0.1",
        "http://host:80",
        "tcp://host:70000",
        "serial:///dev/ttyUSB0",
        "serial://ttyUSB0?baud=57600",
        "serial:///dev/ttyUSB0?baud=0",
        "SIM",
        "",
    ],
)
def test_invalid_connection(tmp_path: Path, url: str) -> None:
    msg = error(tmp_path, with_("carrier", connection=url))
    assert "carrier.connection" in msg


def test_unit_connection_cannot_mix_sim_and_real(tmp_path: Path) -> None:
    data = with_(
        "rovers",
        units=[{"id": "x", "sysid": 20, "connection": "udp://10.0.0.5:14550"}, {"id": "y", "sysid": 21}],
    )
    assert "rovers.units[0].connection" in error(tmp_path, data)


def test_deploy_range_and_energy_both_or_neither(tmp_path: Path) -> None:
    both = with_("rovers", energy={"initial": 10, "task": 2, "rho": 1})
    assert "exactly one of 'deploy_range'" in error(tmp_path, both)
    neither = with_("rovers", deploy_range=None)
    assert "rovers.deploy_range: give exactly one" in error(tmp_path, neither)


def test_energy_terms_must_leave_energy_to_fly(tmp_path: Path) -> None:
    data = with_("rovers", deploy_range=None, energy={"initial": 10, "task": 10, "rho": 1})
    assert "rovers.energy.task" in error(tmp_path, data)


def test_endurance_below_deploy_range(tmp_path: Path) -> None:
    assert "rovers.endurance_range" in error(tmp_path, with_("rovers", endurance_range=10))


def test_both_fleet_and_units(tmp_path: Path) -> None:
    data = with_("rovers", fleet={"count": 2}, units=[{"id": "x", "sysid": 20}])
    assert "rovers.units: give either 'fleet" in error(tmp_path, data)


@pytest.mark.parametrize(
    ("fault", "where", "what"),
    [
        ({"kind": "explode"}, "kind", "use one of: dropout"),
        ({"kind": "dropot"}, "kind", "did you mean 'dropout'"),
        ({"kind": "packet_loss"}, "rate", "needs 'rate:'"),
        ({"kind": "packet_loss", "rate": 1.5}, "rate", "<= 1"),
        ({"kind": "dropout", "factor": 2}, "factor", "does not apply"),
        ({"kind": "dropout", "vehicle": "r9"}, "vehicle", "not a vehicle"),
        ({"kind": "dropout", "at": 10, "until": 5}, "until", "later than at"),
    ],
)
def test_invalid_faults(tmp_path: Path, fault: dict[str, Any], where: str, what: str) -> None:
    msg = error(tmp_path, sim={"faults": [{"kind": "latency", "seconds": 0.1}, fault]})
    assert f"sim.faults[1].{where}" in msg and what in msg


def test_collection_rover_not_in_fleet(tmp_path: Path) -> None:
    msg = error(tmp_path, collection={"rovers": [{"id": "r7", "position": [0, 0], "range": 5}]})
    assert "collection.rovers[0].id" in msg and "not a rover of the fleet" in msg


def test_invalid_mqtt(tmp_path: Path) -> None:
    assert "mqtt.url" in error(tmp_path, mqtt={"url": "http://broker"})
    assert "mqtt.tls.key" in error(tmp_path, mqtt={"url": "mqtt://b", "tls": {"cert": "c.pem"}})


def test_invalid_roadmap_parameters(tmp_path: Path) -> None:
    assert "planner.roadmap.phi" in error(tmp_path, planner={"roadmap": {"phi": 1.5}})
    assert "planner.roadmap.xi5: unknown key" in error(tmp_path, planner={"roadmap": {"xi5": 1}})


def test_origin_out_of_range(tmp_path: Path) -> None:
    assert "origin.lat" in error(tmp_path, origin={"lat": 95, "lon": 0, "alt": 0})


@pytest.mark.parametrize(
    "text",
    [
        "tasks: 5\n",
        "carrier: null\n",
        "? [a]\n: b\n",
        "rovers: !!python/object:os.system x\n",
        "\t- x\n",
        "name: [unclosed\n",
        "1: 2\n",
        "tasks: [[1, 2]]\n",
    ],
)
def test_garbage_never_gives_a_traceback(tmp_path: Path, text: str) -> None:
    error(tmp_path, text)
