"""fleetctl.mission: the field-safety keys (docs/field-safety.md): preflight fault kinds,
links.failsafe and geofence - one test per rule, errors naming file:line, key and the fix."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from fleetctl.mission import Mission, MissionError, load_mission
from fleetctl.mission.model import FAULT_KINDS
from sitl.faults import KINDS as SIM_KINDS

ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}
BASE: dict[str, Any] = {
    "name": "t",
    "origin": ORIGIN,
    "carrier": {"position": [0, 0], "max_speed": 15.0},
    "rovers": {"max_speed": 1.0, "deploy_range": 25.0},
    "tasks": [{"id": "a", "position": [10, 20, 4]}, {"id": "b", "position": [40, 10]}],
}
SQUARE = [[-10, -10], [60, -10], [60, 40], [-10, 40]]


def load(tmp_path: Path, **changes: Any) -> Mission:
    data = copy.deepcopy(BASE)
    data.update(changes)
    f = tmp_path / "m.yaml"
    f.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return load_mission(f)


def error(tmp_path: Path, **changes: Any) -> str:
    with pytest.raises(MissionError) as info:
        load(tmp_path, **changes)
    return str(info.value)


def test_fault_kinds_are_the_simulators() -> None:
    assert set(FAULT_KINDS) == set(SIM_KINDS)
    assert {"no_gps", "unhealthy", "low_battery"} <= set(FAULT_KINDS)


def test_preflight_faults_load(tmp_path: Path) -> None:
    m = load(
        tmp_path,
        sim={
            "faults": [
                {"vehicle": "r1", "kind": "no_gps"},
                {"kind": "unhealthy", "at": 5},
                {"vehicle": "r2", "kind": "low_battery", "level": 0.05},
            ]
        },
    )
    kinds = [(f.kind, f.vehicle, f.level) for f in m.sim.faults]
    assert kinds == [("no_gps", "r1", None), ("unhealthy", None, None), ("low_battery", "r2", 0.05)]


def test_low_battery_needs_a_level_in_range(tmp_path: Path) -> None:
    msg = error(tmp_path, sim={"faults": [{"kind": "low_battery"}]})
    assert "sim.faults[0].level" in msg and "needs 'level:'" in msg
    msg = error(tmp_path, sim={"faults": [{"kind": "low_battery", "level": 1.5}]})
    assert "m.yaml:" in msg and "sim.faults[0].level" in msg and "<= 1" in msg
    msg = error(tmp_path, sim={"faults": [{"kind": "no_gps", "level": 0.5}]})
    assert "'level' does not apply to kind no_gps" in msg


def test_links_failsafe(tmp_path: Path) -> None:
    assert load(tmp_path).links.failsafe == "keep"
    assert load(tmp_path, links={"failsafe": "rtl"}).links.failsafe == "rtl"
    msg = error(tmp_path, links={"failsafe": "hover"})
    assert "links.failsafe" in msg and "keep, hold, land, rtl" in msg


def test_geofence_polygon_enu(tmp_path: Path) -> None:
    m = load(
        tmp_path,
        obstacles=[[[20, 0], [25, 0], [25, 5]]],
        bounds=[[-20, -20], [80, 80]],
        geofence={"polygon": SQUARE, "alt_max": 30, "action": "rtl"},
    )
    g = m.geofence
    assert g is not None and g.polygon == tuple(tuple(map(float, p)) for p in SQUARE)
    assert g.alt_max == 30.0 and g.action == "rtl"
    assert g.exclusions == (((20.0, 0.0), (25.0, 0.0), (25.0, 5.0)),)
    assert load(tmp_path).geofence is None


def test_geofence_latlon_vertices(tmp_path: Path) -> None:
    from fleetctl.geo import Origin, local_to_geodetic

    o = Origin(ORIGIN["lat"], ORIGIN["lon"], ORIGIN["alt"])
    pts = [dict(zip(("lat", "lon"), local_to_geodetic(x, y, 0.0, o)[:2], strict=True)) for x, y in SQUARE]
    g = load(tmp_path, geofence={"polygon": pts}).geofence
    assert g is not None and g.action == "report" and g.alt_max is None
    for (x, y), (gx, gy) in zip(SQUARE, g.polygon, strict=True):
        assert abs(x - gx) < 0.01 and abs(y - gy) < 0.01


def test_geofence_from_bounds(tmp_path: Path) -> None:
    g = load(tmp_path, bounds=[[-5, -5], [50, 30]], geofence={"from": "bounds", "action": "hold"}).geofence
    assert g is not None and g.polygon == ((-5.0, -5.0), (50.0, -5.0), (50.0, 30.0), (-5.0, 30.0))
    assert "'from: bounds' needs the mission's 'bounds" in error(tmp_path, geofence={"from": "bounds"})


def test_geofence_rejections(tmp_path: Path) -> None:
    msg = error(tmp_path, geofence={"polygon": SQUARE, "colour": "red"})
    assert "geofence.colour: unknown key" in msg and "m.yaml:" in msg
    assert "exactly one of" in error(tmp_path, geofence={"alt_max": 10})
    assert "exactly one of" in error(
        tmp_path, bounds=[[-5, -5], [50, 30]], geofence={"polygon": SQUARE, "from": "bounds"}
    )
    msg = error(tmp_path, geofence={"polygon": [[0, 0], [10, 0]]})
    assert "geofence.polygon" in msg and "at least 3 vertices" in msg
    msg = error(tmp_path, geofence={"polygon": [[0, 0], [10, 10], [10, 0], [0, 10]]})
    assert "self-crossings" in msg
    msg = error(tmp_path, geofence={"polygon": [[-10, -10], [30, -10], [30, 40], [-10, 40]]})
    assert "task 'b' at (40, 10) lies outside the geofence" in msg
    msg = error(tmp_path, geofence={"polygon": [[5, 5], [60, 5], [60, 40], [5, 40]]})
    assert "the carrier's start at (0, 0) lies outside the geofence" in msg
    msg = error(tmp_path, geofence={"polygon": SQUARE, "alt_max": 3})
    assert "geofence.alt_max" in msg and "task 'a' is 4 m high" in msg
    assert "use one of: report, hold, rtl, land" in error(
        tmp_path, geofence={"polygon": SQUARE, "action": "x"}
    )
    msg = error(tmp_path, geofence={"polygon": [[0, 0], "x", [1, 1]]})
    assert "geofence.polygon[1]" in msg and "{lat, lon}" in msg
    no_origin = {k: v for k, v in BASE.items() if k != "origin"}
    f = tmp_path / "n.yaml"
    f.write_text(yaml.safe_dump({**no_origin, "geofence": {"polygon": [{"lat": 1, "lon": 2}] * 3}}))
    with pytest.raises(MissionError, match="needs the mission's 'origin'"):
        load_mission(f)
