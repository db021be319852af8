"""Operators' formats: tasks/obstacles from .plan, GeoJSON, KML and CSV files; plan --export out.

Positions read from files are checked against fleetctl.geo's conversions of the same numbers; the
exported files are re-read with json, the geojson library, shapely and a JSON Schema of
QGroundControl's plan file format (tests/formats/qgc_plan.schema.json).
"""

from __future__ import annotations

import json
import math
import random
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import geojson
import jsonschema
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point, Polygon, shape

import fleetctl.mission.limits as L
from fleetctl.cli import main
from fleetctl.geo import Origin, geodetic_to_local
from fleetctl.mavlink.compile import compile_plan
from fleetctl.mission import Mission, MissionError, load_mission
from fleetctl.mission.formats import copy_data_files, read_tasks
from fleetctl.run.planning import COLLECT_MEET_HEIGHT
from planners import DEPLOY_PLANNERS

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "mission" / "formats"
ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}
ORG = Origin(**ORIGIN)
BOUNDS = [[-200, -200], [300, 300]]


def mission_yaml(tmp_path: Path, tasks: Any, obstacles: Any = None, origin: bool = True,
                 **extra: Any) -> Path:
    data: dict[str, Any] = {"name": "formats"}
    if origin:
        data["origin"] = ORIGIN
    data |= {"carrier": {"position": [0, 0], "max_speed": 15.0},
             "rovers": {"max_speed": 1.0, "deploy_range": 25.0, "fleet": {"count": 8}}, "tasks": tasks}
    if obstacles is not None:
        data |= {"obstacles": obstacles, "bounds": BOUNDS}
    data |= extra
    f = tmp_path / "m.yaml"
    f.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return f


def load_with(tmp_path: Path, name: str, obstacles: bool = False, **kw: Any) -> Mission:
    """The data file ``name`` copied next to a mission that reads its tasks (and obstacles) from it."""
    shutil.copy(DATA / name, tmp_path / name)
    return load_mission(mission_yaml(tmp_path, {"file": name}, {"file": name} if obstacles else None, **kw))


def error(tmp_path: Path, tasks: Any, obstacles: Any = None, **kw: Any) -> str:
    with pytest.raises(MissionError) as info:
        load_mission(mission_yaml(tmp_path, tasks, obstacles, **kw))
    msg = str(info.value)
    assert msg.startswith(str(tmp_path / "m.yaml")) and "Traceback" not in msg, msg
    return msg


def enu(lat: float, lon: float, z: float) -> tuple[float, float, float]:
    """What a task at (lat, lon) and height z above the origin's altitude is in the mission frame."""
    return geodetic_to_local(lat, lon, ORG.alt + z, ORG)


def assert_tasks(m: Mission, expected: dict[str, tuple[float, float, float]], tol: float = 1e-6) -> None:
    assert [t.id for t in m.tasks] == list(expected)
    for t in m.tasks:
        assert t.position == pytest.approx(expected[t.id], abs=tol), t.id


def polygon_enu(latlon: list[tuple[float, float]]) -> Polygon:
    return Polygon([geodetic_to_local(lat, lon, ORG.alt, ORG)[:2] for lat, lon in latlon])


BARN = [(47.3985, 8.5460), (47.3985, 8.5463), (47.3987, 8.5463), (47.3987, 8.5460)]


# ------------------------------------------------------------------------------------ inputs


def test_plan_waypoints_become_tasks_with_altitudes_by_frame(tmp_path: Path) -> None:
    m = load_with(tmp_path, "site.plan", obstacles=True)
    # take-off, complex item and landing are skipped; home is 490 m, the origin 488 m
    assert_tasks(m, {"site-1": enu(47.3981, 8.5461, 6 + 2.0),  # frame 3: relative to the planned home
                     "site-2": enu(47.3979, 8.5470, 497 - 488.0),  # frame 0: AMSL
                     "site-3": enu(47.3976, 8.5452, 4 + 2.0)})  # frame 6 (relative, _INT)


def test_plan_geofence_exclusions_become_obstacles(tmp_path: Path) -> None:
    m = load_with(tmp_path, "site.plan", obstacles=True)
    assert len(m.obstacles) == 2  # the two inclusion zones are not obstacles
    assert Polygon(m.obstacles[0]).symmetric_difference(polygon_enu(BARN)).area < 1e-6
    circle = Polygon(m.obstacles[1])
    x, y, _ = geodetic_to_local(47.3984, 8.5450, ORG.alt, ORG)
    assert len(m.obstacles[1]) == 16
    assert circle.contains(Point(x, y).buffer(6.0 - 1e-6, 64))  # the 16-gon never cuts into the circle
    assert circle.area < math.pi * 36 * 1.03


def test_plan_without_origin_quotes_its_planned_home(tmp_path: Path) -> None:
    shutil.copy(DATA / "site.plan", tmp_path)
    msg = error(tmp_path, {"file": "site.plan"}, origin=False)
    assert "tasks.file: site.plan: mission.items[1]: lat/lon positions need the mission's 'origin" in msg
    assert "planned home is lat 47.3977420, lon 8.5455940, alt 490" in msg


def test_plan_terrain_frame_is_refused(tmp_path: Path) -> None:
    doc = json.loads((DATA / "site.plan").read_text())
    doc["mission"]["items"][2]["frame"] = 10
    (tmp_path / "t.plan").write_text(json.dumps(doc))
    msg = error(tmp_path, {"file": "t.plan"})
    assert "t.plan: mission.items[2]: frame 10 (GLOBAL_TERRAIN_ALT)" in msg and "Relative or AMSL" in msg


def test_plan_that_is_not_a_plan(tmp_path: Path) -> None:
    (tmp_path / "t.plan").write_text('{"fileType": "GeoFence"}')
    assert "not a QGroundControl plan (fileType 'GeoFence'" in error(tmp_path, {"file": "t.plan"})


def test_geojson_points_and_polygons(tmp_path: Path) -> None:
    m = load_with(tmp_path, "site.geojson", obstacles=True)
    # ids: properties.id, properties.name, the Feature's id, generated; the 'stop' point is skipped
    assert_tasks(m, {"mast": enu(47.39873, 8.54758, 15.0), "gate": enu(47.39896, 8.5448, 0.0),
                     "7": enu(47.3981, 8.5461, 4.5), "site-4": enu(47.3978, 8.5465, 1.0)})
    assert len(m.obstacles) == 3  # barn, and the MultiPolygon's two sheds; the LineString is skipped
    barn = Polygon(m.obstacles[0])
    assert not barn.interiors  # the hole stays blocked
    assert barn.symmetric_difference(polygon_enu(BARN)).area < 1e-6
    assert Polygon(m.obstacles[1]).symmetric_difference(
        polygon_enu([(47.3970, 8.5440), (47.3970, 8.5442), (47.3971, 8.5442)])).area < 1e-6


def test_kml_placemarks_with_altitude_modes(tmp_path: Path) -> None:
    m = load_with(tmp_path, "site.kml", obstacles=True)
    # absolute: alt - origin.alt; no altitudeMode = clampToGround (the 40 m is ignored); relativeToGround
    assert_tasks(m, {"mast": enu(47.39873, 8.54758, 15.0), "pm-gate": enu(47.39896, 8.5448, 0.0),
                     "roof": enu(47.3981, 8.5461, 9.5)})
    assert len(m.obstacles) == 1
    assert Polygon(m.obstacles[0]).symmetric_difference(polygon_enu(BARN)).area < 1e-6


def test_csv_geodetic_local_and_obstacles(tmp_path: Path) -> None:
    m = load_with(tmp_path, "site.csv")
    assert_tasks(m, {"mast": enu(47.39873, 8.54758, 15.0), "gate": enu(47.39896, 8.5448, 0.0),
                     "roof": enu(47.3981, 8.5461, 9.5)})
    shutil.copy(DATA / "site_local.csv", tmp_path)
    shutil.copy(DATA / "obstacles.csv", tmp_path)
    f = mission_yaml(tmp_path, {"file": "site_local.csv"}, {"file": "obstacles.csv"}, origin=False)
    m = load_mission(f)
    assert_tasks(m, {"a": (10.0, 20.0, 4.0), "b": (40.0, 10.0, 0.0)})
    assert m.obstacles == (((20.0, 20.0), (30.0, 20.0), (30.0, 40.0), (20.0, 40.0)),
                           ((60.0, 60.0), (70.0, 60.0), (65.0, 70.0)))


def test_the_same_tasks_from_every_format_plan_alike(tmp_path: Path) -> None:
    plans = []
    for name in ("site.kml", "site.csv"):
        m = load_with(tmp_path, name)
        plans.append(DEPLOY_PLANNERS["lee"](m.deploy_problem()).to_json())
    assert plans[0]["makespan"] == pytest.approx(plans[1]["makespan"], abs=1e-5)
    targets = [[(r["task"], *r["target"]) for s in p["stops"] for r in s["rovers"]] for p in plans]
    assert [t[0] for t in targets[1]] == ["roof", "mast", "gate"]  # the KML's gate is 'pm-gate' (no name)
    coords = [[c for t in ts for c in t[1:]] for ts in targets]
    assert coords[0] == pytest.approx(coords[1], abs=1e-5)


# ------------------------------------------------------------------------------------ bad inputs


def test_swapped_axis_order_gets_a_hint(tmp_path: Path) -> None:
    doc = json.loads((DATA / "site.geojson").read_text())
    lon, lat, alt = doc["features"][2]["geometry"]["coordinates"]
    doc["features"][2]["geometry"]["coordinates"] = [lat, lon, alt]
    (tmp_path / "t.geojson").write_text(json.dumps(doc))
    msg = error(tmp_path, {"file": "t.geojson"})
    assert "tasks.file: t.geojson: features[2]: lat 8.5461000, lon 47.3981000 lies" in msg
    assert "latitude and longitude look swapped" in msg and "longitude first" in msg


def test_latitude_out_of_range_swapped_gets_the_hint(tmp_path: Path) -> None:
    (tmp_path / "t.csv").write_text("id,lat,lon\na,8.5461,147.3981\nb,100.5,8.5\n")
    msg = error(tmp_path, {"file": "t.csv"})
    assert "t.csv: line 2: lat 8.5461000, lon 147.3981000" in msg and "swapped" not in msg
    (tmp_path / "t.csv").write_text("id,lat,lon\nb,147.3981,47.0\n")
    assert "not a position on Earth" in error(tmp_path, {"file": "t.csv"})


def test_csv_missing_columns_and_bad_cells(tmp_path: Path) -> None:
    (tmp_path / "t.csv").write_text("id,lat,alt\na,47.39,490\n")
    msg = error(tmp_path, {"file": "t.csv"})
    assert "t.csv: line 1: missing column(s) lon: the header names id, lat, alt; give id,lat,lon" in msg
    (tmp_path / "t.csv").write_text("id;lat;lon\na;47.39;8.54\n")
    assert "separate the columns with commas" in error(tmp_path, {"file": "t.csv"})
    (tmp_path / "t.csv").write_text("id,x,y,z\na,1,2,3\nb,4,five,6\n")
    assert "t.csv: line 3: column y: 'five' is not a number" in error(tmp_path, {"file": "t.csv"})
    (tmp_path / "t.csv").write_text("id,x,y,hieght\na,1,2,3\n")
    assert "unknown column 'hieght': did you mean 'height'?" in error(tmp_path, {"file": "t.csv"})


def test_unknown_extension_and_missing_file(tmp_path: Path) -> None:
    (tmp_path / "t.kmz").write_bytes(b"PK")
    msg = error(tmp_path, {"file": "t.kmz"})
    assert "tasks.file: t.kmz: unknown file type '.kmz'; use one of .plan, .geojson, .json, .kml, .csv" in msg
    assert "cannot read the file" in error(tmp_path, {"file": "nope.geojson"})
    assert "unknown key; allowed keys here: file" in error(tmp_path, {"path": "t.csv"})


@pytest.mark.parametrize("name", ["bomb.kml", "external_entity.kml"])
def test_xml_entities_are_refused(tmp_path: Path, name: str) -> None:
    shutil.copy(DATA / name, tmp_path)
    msg = error(tmp_path, {"file": name})
    assert f"tasks.file: {name}: refused: the file declares a DTD or entities" in msg
    assert "root:" not in msg and "aaaa" not in msg


def test_oversize_file_is_refused_before_parsing(tmp_path: Path) -> None:
    (tmp_path / "big.geojson").write_text('{"type": "FeatureCollection", "features": []}'
                                          + " " * L.MAX_DATA_FILE_BYTES)
    assert f"big.geojson: the file is larger than {L.MAX_DATA_FILE_BYTES} bytes" in error(
        tmp_path, {"file": "big.geojson"})


def test_too_many_entries_and_deep_json(tmp_path: Path) -> None:
    feat = '{"type": "Feature", "properties": {}, "geometry": null}'
    feats = ",".join([feat] * (L.MAX_DATA_FILE_ENTRIES + 1))
    (tmp_path / "many.geojson").write_text('{"type": "FeatureCollection", "features": [' + feats + "]}")
    assert f"{L.MAX_DATA_FILE_ENTRIES + 1} features are too many" in error(tmp_path, {"file": "many.geojson"})
    (tmp_path / "deep.geojson").write_text("[" * 200_000 + "]" * 200_000)
    assert "nested too deeply" in error(tmp_path, {"file": "deep.geojson"})


def test_malformed_json_names_line_and_column(tmp_path: Path) -> None:
    (tmp_path / "t.geojson").write_text('{"type": "FeatureCollection",\n "features": [,]}')
    assert "t.geojson: line 2 column 15: malformed JSON" in error(tmp_path, {"file": "t.geojson"})


def test_later_checks_name_the_file_and_feature(tmp_path: Path) -> None:
    shutil.copy(DATA / "site.geojson", tmp_path)
    m = mission_yaml(tmp_path, {"file": "site.geojson"})
    text = m.read_text().replace("deploy_range: 25.0", "deploy_range: 10.0")
    m.write_text(text)
    with pytest.raises(MissionError) as info:
        load_mission(m)
    assert "tasks[0] (from site.geojson features[0]): task 'mast' is 15 m high" in str(info.value)
    (tmp_path / "dup.csv").write_text("id,x,y\na,1,1\na,2,2\n")
    msg = error(tmp_path, {"file": "dup.csv"})
    assert "tasks[1].id (from dup.csv line 3): duplicate task id 'a'" in msg


def test_bad_file_through_the_command_line_exits_2(tmp_path: Path) -> None:
    shutil.copy(DATA / "bomb.kml", tmp_path)
    m = mission_yaml(tmp_path, {"file": "bomb.kml"})
    res = subprocess.run([sys.executable, "-m", "fleetctl.cli", "plan", "--mission", str(m)],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert res.stderr.startswith(f"fleetctl: error: {m}:") and "bomb.kml: refused" in res.stderr


# ------------------------------------------------------------------------------------ outputs

SCHEMA = jsonschema.Draft202012Validator(json.loads((DATA / "qgc_plan.schema.json").read_text()))
RECON = ROOT / "missions" / "recon.yaml"


@pytest.fixture(scope="module")
def recon_export(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("export")
    assert main(["plan", "--mission", str(RECON), "--json", "--export", str(out)]) == 0
    return out


def _no_constant(name: str) -> None:
    raise AssertionError(f"{name} in an exported file (not JSON)")


def test_export_json_stdout_is_unchanged(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--mission", str(RECON), "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert main(["plan", "--mission", str(RECON), "--json", "--export", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    exported = json.loads(cap.out)  # only the plan JSON on stdout
    plain.pop("compute_ms"), exported.pop("compute_ms")
    assert exported == plain and "exported 17 QGroundControl .plan files and plan.geojson" in cap.err


def test_exported_plans_follow_the_qgroundcontrol_format(recon_export: Path) -> None:
    out = recon_export
    m = load_mission(RECON)
    assert sorted(p.name for p in out.glob("*.plan")) == sorted(f"{v}.plan" for v in (m.carrier.id,
                                                                                       *m.rovers.ids[:16]))
    for f in out.glob("*.plan"):
        doc = json.loads(f.read_text(), parse_constant=_no_constant)  # no NaN/Infinity: strict JSON
        errors = [f"{'/'.join(map(str, e.absolute_path))}: {e.message}" for e in SCHEMA.iter_errors(doc)]
        assert not errors, (f.name, errors[:5])


def test_the_schema_accepts_qgroundcontrols_own_files_and_refuses_broken_ones(recon_export: Path) -> None:
    assert not list(SCHEMA.iter_errors(json.loads((DATA / "site.plan").read_text())))  # QGC-written style
    good = json.loads((recon_export / "r1.plan").read_text())
    broken = [("fileType", None), ("version", 2)]
    for key, value in broken:
        doc = json.loads(json.dumps(good))
        doc.pop(key) if value is None else doc.__setitem__(key, value)
        assert list(SCHEMA.iter_errors(doc)), key
    for change in ({"params": [0, 0, 0, 0, 47.0, 8.0]}, {"frame": "3"}, {"type": "Simple"}, {"doJumpId": 0}):
        doc = json.loads(json.dumps(good))
        doc["mission"]["items"][0].update(change)
        assert list(SCHEMA.iter_errors(doc)), change
    doc = json.loads(json.dumps(good))
    doc["mission"]["plannedHomePosition"] = [147.4, 8.5, 488.0]  # latitude > 90
    assert list(SCHEMA.iter_errors(doc))


def test_vehicle_ids_become_safe_file_names() -> None:
    from fleetctl.mission.formats.plan_export import file_name

    assert [file_name(v) for v in ("r1", "carrier-2.b", "../etc/x", "a b")] == ["r1", "carrier-2.b", "_etc_x",
                                                                                "a_b"]


def test_exported_items_are_the_compiled_mission_items(recon_export: Path) -> None:
    out = recon_export
    m = load_mission(RECON)
    plan = DEPLOY_PLANNERS["lee"](m.deploy_problem())
    compiled = compile_plan(plan, m.origin, carrier_id=m.carrier.id, meet_height=COLLECT_MEET_HEIGHT)
    for vid, items in compiled.missions.items():
        doc = json.loads((out / f"{vid}.plan").read_text())
        got = doc["mission"]["items"]
        assert len(got) == len(items)
        for seq, (g, it) in enumerate(zip(got, items, strict=True), 1):
            assert (g["command"], g["doJumpId"], g["frame"], g["autoContinue"]) == (it.command, seq, 3, True)
            want = [it.param1, it.param2, it.param3, it.param4, it.lat, it.lon, it.z]
            assert g["params"] == [None if math.isnan(w) else pytest.approx(w, abs=1e-9) for w in want]
            assert g["Altitude"] == pytest.approx(it.z) and g["AMSLAltAboveTerrain"] is None
        home = doc["mission"]["plannedHomePosition"]
        assert home[2] == m.origin.alt and doc["mission"]["firmwareType"] == 0
    carrier = json.loads((out / "carrier.plan").read_text())["mission"]
    assert carrier["plannedHomePosition"][:2] == pytest.approx([ORG.lat, ORG.lon], abs=1e-9)
    assert carrier["cruiseSpeed"] == m.carrier.max_speed and carrier["vehicleType"] == 10


def test_exported_geojson_is_valid_and_matches_the_plan(recon_export: Path) -> None:
    out = recon_export
    m = load_mission(RECON)
    plan = DEPLOY_PLANNERS["lee"](m.deploy_problem())
    text = (out / "plan.geojson").read_text()
    fc = geojson.loads(text)  # a second GeoJSON implementation (it rounds coordinates to 1e-6 degrees)
    assert fc.is_valid, fc.errors()
    assert len(fc["features"]) == len(json.loads(text)["features"])
    by_kind: dict[str, list[Any]] = {}
    for f in json.loads(text)["features"]:
        by_kind.setdefault(f["properties"]["kind"], []).append(f)
    counts = {k: len(v) for k, v in by_kind.items()}
    assert counts == {"task": 16, "carrier_route": 1, "stop": len(plan.stops), "rover_flight": 16}
    for f, t in zip(by_kind["task"], m.tasks, strict=True):
        lon, lat, alt = f["geometry"]["coordinates"]  # RFC 7946: longitude first
        assert f["properties"]["id"] == t.id
        assert geodetic_to_local(lat, lon, alt, ORG) == pytest.approx(t.position, abs=1e-6)
    route = shape(by_kind["carrier_route"][0]["geometry"])
    assert isinstance(route, LineString)
    assert route.coords[0][:2] == pytest.approx((ORG.lon, ORG.lat), abs=1e-9)  # from the carrier's start
    ends = [geodetic_to_local(c[1], c[0], ORG.alt, ORG)[:2] for c in route.coords]
    assert LineString(ends).length == pytest.approx(plan.carrier_distance, rel=1e-6)
    flights = {f["properties"]["rover"]: f for f in by_kind["rover_flight"]}
    for k, stop in enumerate(plan.stops):
        for leg in stop.rovers:
            p = flights[leg.rover]["properties"]
            assert (p["task"], p["stop"], p["depart"], p["arrive"]) == (leg.task, k, stop.depart, leg.arrive)
            lon, lat, alt = shape(flights[leg.rover]["geometry"]).coords[-1]
            assert geodetic_to_local(lat, lon, alt, ORG) == pytest.approx(leg.end, abs=1e-6)


def test_exported_files_read_back_as_tasks(recon_export: Path) -> None:
    out = recon_export
    m = load_mission(RECON)
    back = read_tasks(out / "plan.geojson", m.origin)  # the stops are skipped (kind: stop)
    assert [t.id for t in back] == [t.id for t in m.tasks]
    for b, t in zip(back, m.tasks, strict=True):
        assert b.position == pytest.approx(t.position, abs=1e-6)
    plan = DEPLOY_PLANNERS["lee"](m.deploy_problem())
    for leg in plan.legs():  # a rover's plan: its one waypoint is its task (1e-7 degrees ~ 1 cm)
        (wp,) = read_tasks(out / f"{leg.rover}.plan", m.origin)
        assert wp.position == pytest.approx(leg.end, abs=0.02)
    stops = read_tasks(out / "carrier.plan", m.origin)
    assert [s.position for s in stops] == [pytest.approx(s.position, abs=0.02) for s in plan.stops]


def test_export_round_trips_obstacles_and_geofence(tmp_path: Path) -> None:
    poly = [[20, 20], [30, 20], [30, 40], [20, 40]]
    f = mission_yaml(tmp_path, [{"id": "a", "position": [50, 30, 3]}, {"id": "b", "position": [10, 60, 2]}],
                     [poly], geofence={"from": "bounds"},
                     planner={"roadmap": {"xi1": 0.2, "xi2": 20, "xi3": 0.1, "xi4": 10}})
    assert main(["plan", "--mission", str(f), "--export", str(tmp_path / "out")]) == 0
    doc = json.loads((tmp_path / "out" / "carrier.plan").read_text())
    assert not list(SCHEMA.iter_errors(doc))
    fence = doc["geoFence"]["polygons"]
    assert [z["inclusion"] for z in fence] == [True, False]
    m2 = load_mission(mission_yaml(tmp_path, [{"id": "a", "position": [50, 30, 3]}],
                                   {"file": "out/carrier.plan"}))
    assert Polygon(m2.obstacles[0]).symmetric_difference(Polygon(poly)).area < 1e-3
    m3 = load_mission(mission_yaml(tmp_path, {"file": "out/plan.geojson"}, {"file": "out/plan.geojson"}))
    assert [t.id for t in m3.tasks] == ["a", "b"]
    assert Polygon(m3.obstacles[0]).symmetric_difference(Polygon(poly)).area < 1e-6


def test_export_needs_an_origin(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = mission_yaml(tmp_path, [{"id": "a", "position": [10, 20, 3]}], origin=False)
    assert main(["plan", "--mission", str(f), "--export", str(tmp_path / "out")]) == 2
    assert "--export needs the mission's origin" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------------------------ the example


def test_recon_geojson_plans_as_recon(capsys: pytest.CaptureFixture[str]) -> None:
    plans = []
    for name in ("recon.yaml", "recon_geojson.yaml"):
        assert main(["plan", "--mission", str(ROOT / "missions" / name), "--json"]) == 0
        plan = json.loads(capsys.readouterr().out)
        plan.pop("compute_ms")
        plans.append(plan)
    # the tasks agree to 1e-6 m (WGS84 round trip); the planner's search may settle on a route a
    # hair apart from such a difference: the same tasks, and the same makespan to 0.01 %
    served = [sorted(r["task"] for st in p["stops"] for r in st["rovers"]) for p in plans]
    assert served[0] == served[1]
    assert plans[0]["makespan"] == pytest.approx(plans[1]["makespan"], rel=1e-4)
    assert plans[0]["time_model"] == plans[1]["time_model"]
    a = load_mission(ROOT / "missions" / "recon.yaml")
    b = load_mission(ROOT / "missions" / "recon_geojson.yaml")
    assert [t.id for t in a.tasks] == [t.id for t in b.tasks]
    for ta, tb in zip(a.tasks, b.tasks, strict=True):
        assert ta.position == pytest.approx(tb.position, abs=1e-6)


def test_recon_geojson_is_recon_but_for_its_tasks() -> None:
    a, b = (yaml.safe_load((ROOT / "missions" / n).read_text()) for n in ("recon.yaml", "recon_geojson.yaml"))
    assert b.pop("tasks") == {"file": "recon_tasks.geojson"} and b.pop("name") == "recon_geojson"
    a.pop("tasks"), a.pop("name")
    assert b == a, "keep missions/recon_geojson.yaml in step with recon.yaml"


def test_data_files_are_copied_for_the_run_folder_copy(tmp_path: Path) -> None:
    m = load_mission(ROOT / "missions" / "recon_geojson.yaml")
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(m.path, run / "mission.yaml")
    assert copy_data_files(m, run) == [run / "recon_tasks.geojson"]
    assert load_mission(run / "mission.yaml").tasks == m.tasks  # what `fleetctl resume` loads
    shutil.copy(m.path.parent / "recon_tasks.geojson", tmp_path / "plan.json")  # named like a run record
    f = mission_yaml(tmp_path, {"file": "plan.json"}, rovers={"max_speed": 1.0, "deploy_range": 25.0})
    assert copy_data_files(load_mission(f), run) == [] and not (run / "plan.json").exists()


async def test_a_run_folder_holds_the_export_and_the_task_file(tmp_path: Path) -> None:
    from fleetctl.run.flight import execute

    (tmp_path / "tasks.csv").write_text("id,x,y,z\nt1,20,10,5\nt2,40,-10,4\n")
    f = mission_yaml(tmp_path, {"file": "tasks.csv"}, sim={"speedup": 20.0},
                     carrier={"position": [0, 0], "max_speed": 10.0, "accel": 5.0, "unload_time": 1.0},
                     rovers={"max_speed": 5.0, "deploy_range": 40.0, "fleet": {"count": 2}})
    m = load_mission(f)
    out = await execute(m, "deploy", runs_dir=tmp_path / "runs")
    assert out.exit_code == 0, out.error
    run = out.run_dir
    assert run is not None and load_mission(run / "mission.yaml").tasks == m.tasks  # what resume loads
    plans = {p.stem: json.loads(p.read_text()) for p in (run / "export").glob("*.plan")}
    assert sorted(plans) == ["carrier", "r1", "r2"]
    records = [json.loads(line) for line in (run / "journal.jsonl").read_text().splitlines()]
    uploads = {r["vehicle"]: r["items"] for r in records
               if r["kind"] == "command" and r.get("command") == "upload_mission"}
    assert sorted(uploads) == sorted(plans)
    for vid, doc in plans.items():
        assert not list(SCHEMA.iter_errors(doc)), vid
        assert len(doc["mission"]["items"]) == uploads[vid], vid  # the items uploaded (PX4-style sim)
        assert doc["mission"]["firmwareType"] == 12  # from the vehicle's HEARTBEAT
    assert geojson.loads((run / "export" / "plan.geojson").read_text()).is_valid


def test_mqtt_task_messages_work_with_obstacles_from_a_file(tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    from fleetctl.bus.client import FleetBus
    from fleetctl.bus.config import BusConfig
    from fleetctl.bus.task_messages import TaskMessageError

    shutil.copy(DATA / "obstacles.csv", tmp_path)
    f = mission_yaml(tmp_path, [{"id": "a", "position": [10, 10, 3]}], {"file": "obstacles.csv"})
    m = load_mission(f)
    monkeypatch.chdir(ROOT)  # relative data files start at the mission's folder, not the working directory
    bus = FleetBus(BusConfig("127.0.0.1", 1883, "t"), m)
    added = bus.rules.add({"tasks": [{"id": "n", "position": [50, 50, 2]}]}, "P/tasks/add")[0]
    assert [t.id for t in added] == ["n"]
    with pytest.raises(TaskMessageError, match="lies inside obstacles"):
        bus.rules.add({"id": "x", "position": [25, 30, 2]}, "P/tasks/add")


def test_run_folder_export_prunes_vehicles_a_replan_left_out(tmp_path: Path) -> None:
    from fleetctl.mission.formats.plan_export import export_plan

    m = load_mission(RECON)
    plan = DEPLOY_PLANNERS["lee"](m.deploy_problem())
    compiled = compile_plan(plan, m.origin, carrier_id=m.carrier.id)
    (tmp_path / "r18.plan").write_text("{}")
    export_plan(m, plan, compiled, tmp_path)
    assert (tmp_path / "r18.plan").exists()  # --export DIR never deletes what it did not write
    export_plan(m, plan, compiled, tmp_path, prune=True)
    assert not (tmp_path / "r18.plan").exists() and (tmp_path / "r16.plan").exists()


def test_ardupilot_home_item_becomes_the_planned_home(tmp_path: Path) -> None:
    from fleetctl.mavlink.autopilots import ArduPilot
    from fleetctl.mission.formats.plan_export import export_plan

    m = load_mission(RECON)
    plan = DEPLOY_PLANNERS["lee"](m.deploy_problem())
    ap = ArduPilot()
    compiled = compile_plan(plan, m.origin, carrier_id=m.carrier.id, autopilot=ap)
    export_plan(m, plan, compiled, tmp_path, autopilots={v: ap for v in compiled.missions})
    for vid, items in compiled.missions.items():
        doc = json.loads((tmp_path / f"{vid}.plan").read_text())
        assert not list(SCHEMA.iter_errors(doc)) and doc["mission"]["firmwareType"] == 3
        assert [i["command"] for i in doc["mission"]["items"]] == [it.command for it in items[1:]]
        assert doc["mission"]["plannedHomePosition"] == [items[0].lat, items[0].lon, items[0].z]
        assert doc["mission"]["items"][0]["doJumpId"] == 1  # QGroundControl inserts home itself


def test_collection_export_homes_at_the_rovers(tmp_path: Path) -> None:
    assert main(["plan", "--mission", str(RECON), "--collect", "--export", str(tmp_path)]) == 0
    m = load_mission(RECON)
    assert m.collection is not None
    for c in m.collection:
        doc = json.loads((tmp_path / f"{c.id}.plan").read_text())
        assert not list(SCHEMA.iter_errors(doc))
        lat, lon, alt = doc["mission"]["plannedHomePosition"]
        assert geodetic_to_local(lat, lon, alt, ORG) == pytest.approx((*c.position[:2], 0.0), abs=1e-6)
        assert [i["command"] for i in doc["mission"]["items"]][-1] == 21  # NAV_LAND on the carrier


_ENU = st.tuples(st.floats(-5000, 5000), st.floats(-5000, 5000), st.floats(0, 20))


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(points=st.lists(_ENU, min_size=1, max_size=5))
def test_any_positions_survive_every_geodetic_format(tmp_path: Path,
                                                     points: list[tuple[float, float, float]]) -> None:
    from fleetctl.geo import local_to_geodetic

    geo = [local_to_geodetic(x, y, z, ORG) for x, y, z in points]  # (lat, lon, alt)
    rows = [(f"t{i}", la, lo, al) for i, (la, lo, al) in enumerate(geo)]
    point = ('{"type": "Feature", "properties": {"id": "%s"}, '
             '"geometry": {"type": "Point", "coordinates": %s}}')
    files = {
        "p.csv": "id,lat,lon,alt\n" + "".join(f"{i},{la!r},{lo!r},{al!r}\n" for i, la, lo, al in rows),
        "p.geojson": '{"type": "FeatureCollection", "features": ['
                     + ",".join(point % (i, json.dumps([lo, la, al])) for i, la, lo, al in rows) + "]}",
        "p.kml": '<kml xmlns="http://www.opengis.net/kml/2.2"><Document>' + "".join(
            f"<Placemark><name>{i}</name><Point><altitudeMode>absolute</altitudeMode>"
            f"<coordinates>{lo!r},{la!r},{al!r}</coordinates></Point></Placemark>"
            for i, la, lo, al in rows) + "</Document></kml>",
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text)
        got = read_tasks(tmp_path / name, ORG)
        assert [t.id for t in got] == [r[0] for r in rows], name
        for t, p in zip(got, points, strict=True):
            assert t.position == pytest.approx(p, abs=1e-6), name


_ODD = [None, True, 0, -1, 1e308, "x", [], {}, [1], [1, 2, 3, 4], "Feature", "Point", [[1, 2]], [[[1, 2]]]]


def _mutated(raw: bytes, name: str, rng: random.Random) -> bytes:
    if name.endswith((".plan", ".geojson")) and rng.random() < 0.6:
        def walk(x: Any) -> Any:
            if rng.random() < 0.08:
                return rng.choice(_ODD)
            if isinstance(x, dict):
                return {k: walk(v) for k, v in x.items() if rng.random() > 0.05}
            if isinstance(x, list):
                return [walk(v) for v in x if rng.random() > 0.05]
            return x
        return json.dumps(walk(json.loads(raw))).encode()
    b = bytearray(raw)
    for _ in range(rng.randint(1, 8)):
        i = rng.randrange(len(b))
        odd_byte = bytes([rng.choice(b',;<>"/0123456789.- \n')])
        b[i:i + 1] = rng.choice([b"", bytes([rng.randrange(256)]), odd_byte])
    return bytes(b)


def test_mutated_files_only_ever_give_format_errors(tmp_path: Path) -> None:
    """Deterministic mutations of the data files (odd JSON values, flipped bytes): readers raise
    FormatError with a message, never another exception."""
    from fleetctl.mission.formats import FormatError, read_obstacles

    rng = random.Random(0)
    names = ["site.plan", "site.geojson", "site.kml", "site.csv", "obstacles.csv"]
    outcomes = {"ok": 0, "refused": 0}
    for _ in range(250):
        name = rng.choice(names)
        (tmp_path / name).write_bytes(_mutated((DATA / name).read_bytes(), name, rng))
        for read in (read_tasks, read_obstacles):
            try:
                read(tmp_path / name, ORG)
                outcomes["ok"] += 1
            except FormatError as exc:
                assert str(exc).startswith(str(tmp_path / name)) and len(str(exc)) < 1000
                outcomes["refused"] += 1
    assert outcomes["ok"] > 20 and outcomes["refused"] > 20, outcomes  # both kinds were exercised


def test_odd_values_found_by_mutation_are_format_errors(tmp_path: Path) -> None:
    kml = (DATA / "site.kml").read_text().replace('encoding="UTF-8"', 'encoding="UT-8"')
    (tmp_path / "t.kml").write_text(kml)
    assert "t.kml: cannot read the XML: unknown encoding" in error(tmp_path, {"file": "t.kml"})
    doc = json.loads((DATA / "site.plan").read_text())
    doc["mission"]["items"][1]["frame"] = [3]
    (tmp_path / "t.plan").write_text(json.dumps(doc))
    msg = error(tmp_path, {"file": "t.plan"})
    assert "t.plan: mission.items[1]: frame must be a MAV_FRAME number, got [3]" in msg
