"""The loader's limits (fleetctl.mission.limits, docs/mission-limits.md): one test per rule."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from fleetctl.mission import limits as L
from fleetctl.mission import load_mission, parse_mission
from fleetctl.mission.yaml_safe import YamlError, read_yaml
from tests.mission.test_mission import BASE, MISSIONS, error, load, with_

BASE_YAML = yaml.safe_dump(BASE, sort_keys=False)


def test_every_shipped_mission_is_within_the_limits() -> None:
    files = sorted(MISSIONS.rglob("*.yaml"))
    assert len(files) >= 29
    for f in files:
        load_mission(f)


# ------------------------------------------------------------------------------------ YAML


def test_file_size_cap(tmp_path: Path) -> None:
    text = BASE_YAML + "# " + "x" * L.MAX_FILE_BYTES + "\n"
    msg = error(tmp_path, text)
    assert f"larger than {L.MAX_FILE_BYTES} bytes" in msg


def test_alias_bomb_is_refused_at_its_line(tmp_path: Path) -> None:
    bomb = ["z0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    bomb += [f"z{k}: &a{k} [{', '.join(f'*a{k - 1}' for _ in range(10))}]" for k in range(1, 10)]
    text = BASE_YAML + "\n".join(bomb) + "\n"
    msg = error(tmp_path, text)
    line = len(BASE_YAML.splitlines()) + 5  # z4 holds 10 x 11,111 values: over the budget
    assert f"m.yaml:{line}: alias *a3 (11111 values)" in msg and "larger than" in msg


@pytest.mark.parametrize("text", ["zz: &r [1, *r]\n", "zz: &m {a: 1, b: *m}\n", "zz: &r [[[*r]]]\n"])
def test_recursive_alias(tmp_path: Path, text: str) -> None:
    msg = error(tmp_path, BASE_YAML + text)
    assert f":{len(BASE_YAML.splitlines()) + 1}: alias" in msg and "recursive alias" in msg


def test_alias_use_budget(tmp_path: Path) -> None:
    text = BASE_YAML + "zz0: &a 1\n" + "".join(f"zz{k}: *a\n" for k in range(1, L.MAX_ALIASES + 2))
    assert f"more than {L.MAX_ALIASES} alias uses" in error(tmp_path, text)


def test_aliases_within_the_budget_still_work(tmp_path: Path) -> None:
    text = BASE_YAML.replace("max_speed: 15.0", "max_speed: &v 15.0")
    text = text.replace("max_speed: 1.0", "max_speed: *v")
    assert load(tmp_path, text).rovers.max_speed == 15.0


@pytest.mark.parametrize("depth", [L.MAX_YAML_DEPTH + 1, 600, 20_000])
def test_deep_nesting(tmp_path: Path, depth: int) -> None:
    msg = error(tmp_path, BASE_YAML + "zz: " + "[" * depth + "]" * depth + "\n")
    assert "nested more than" in msg and f":{len(BASE_YAML.splitlines()) + 1}:" in msg


def test_node_budget_without_aliases() -> None:
    with pytest.raises(YamlError, match="larger than 50 values"):
        from fleetctl.mission.yaml_safe import BoundedLoader

        loader = BoundedLoader("[" + ", ".join(["1"] * 60) + "]", max_nodes=50)
        loader.get_single_node()


def test_line_map_visits_aliases_once() -> None:
    data, lines = read_yaml("a: &x {k: 1}\nb: *x\nc: [*x, *x]\n")
    assert data == {"a": {"k": 1}, "b": {"k": 1}, "c": [{"k": 1}, {"k": 1}]}
    assert lines[("a", "k")] == 1 and ("b", "k") not in lines and lines[("b",)] == 2


@pytest.mark.parametrize("digits", [41, 400, 5000])
def test_long_numbers(tmp_path: Path, digits: int) -> None:
    text = BASE_YAML.replace("max_speed: 15.0", "max_speed: " + "9" * digits)
    assert f"a number written with {digits} characters" in error(tmp_path, text)


def test_big_integer_from_a_parsed_mapping() -> None:
    d = copy.deepcopy(BASE)
    d["carrier"]["max_speed"] = 10**400  # e.g. from JSON (MQTT): no OverflowError
    with pytest.raises(Exception, match=r"carrier.max_speed: an integer of about 40\d digits is out of"):
        parse_mission(d, "mqtt")


@pytest.mark.parametrize("tag", ["!!bool maybe", "!!timestamp 2020-13-45", "!!float abc", "!!int 12x",
                                 "!!python/object/apply:os.system ['true']", "!custom 5", "!!binary +++"])
def test_bad_tags_are_messages(tmp_path: Path, tag: str) -> None:
    text = BASE_YAML.replace("max_speed: 15.0", f"max_speed: {tag}")
    msg = error(tmp_path, text)
    assert ":6: " in msg  # the line of carrier.max_speed


def test_float_written_like_1e20_gets_a_hint(tmp_path: Path) -> None:
    msg = error(tmp_path, with_("carrier", max_speed="1e1"))
    assert "write 1.0e+20" in msg


def test_long_strings(tmp_path: Path) -> None:
    msg = error(tmp_path, name="n" * (L.MAX_STRING + 1))
    assert f"a string of {L.MAX_STRING + 1} characters is too long" in msg


# ------------------------------------------------------------------------------------ lists


def _tasks(n: int) -> list[dict[str, Any]]:
    return [{"id": f"t{i}", "position": [i % 50, i // 50, 0]} for i in range(n)]


def test_too_many_tasks(tmp_path: Path) -> None:
    msg = error(tmp_path, tasks=_tasks(L.MAX_TASKS + 1))
    assert f"tasks: {L.MAX_TASKS + 1} entries are too many; give at most {L.MAX_TASKS}" in msg


def test_max_tasks_is_accepted(tmp_path: Path) -> None:
    """More tasks than one team's rovers (MAX_ROVERS): an operation serves them in sorties."""
    assert L.MAX_TASKS > L.MAX_ROVERS
    d = with_("rovers", fleet={"count": 20, "sysid_start": 2})
    d["operation"] = True
    d["tasks"] = _tasks(L.MAX_TASKS)
    assert len(load(tmp_path, d).tasks) == L.MAX_TASKS


def test_the_documented_limits_are_the_loaders() -> None:
    """Every ``N (`MAX_NAME`)`` of docs/mission-limits.md is the value in fleetctl.mission.limits."""
    import re

    text = (Path(__file__).parents[2] / "docs" / "mission-limits.md").read_text()
    units = {"KiB": 1024, "MiB": 1024 * 1024}
    found = 0
    for m in re.finditer(r"([\d,.]+)\s*(KiB|MiB|polygons|m)?\s*\(`(MAX_[A-Z_]+)`\)", text):
        if not hasattr(L, m.group(3)):
            continue  # a planner's own bound, e.g. MAX_NODES
        value = float(m.group(1).replace(",", "").split("..")[-1]) * units.get(m.group(2) or "", 1)
        assert value == getattr(L, m.group(3)), (m.group(0), getattr(L, m.group(3)))
        found += 1
    assert found >= 15


def _squares(n: int, k: int = 4) -> list[list[list[float]]]:
    """``n`` distinct small polygons of ``k`` vertices far from the tasks."""
    import math

    def vertex(i: int, j: int) -> list[float]:
        a = 2 * math.pi * i / k
        return [1000 + 3 * (j % 100) + math.cos(a), 1000 + 3 * (j // 100) + math.sin(a)]

    return [[vertex(i, j) for i in range(k)] for j in range(n)]


def test_too_many_obstacles(tmp_path: Path) -> None:
    msg = error(tmp_path, obstacles=_squares(L.MAX_OBSTACLES + 1), bounds=[[-5000, -5000], [5000, 5000]])
    assert f"obstacles: {L.MAX_OBSTACLES + 1} entries are too many" in msg


def test_too_many_vertices_in_one_polygon(tmp_path: Path) -> None:
    wide = [[-5000, -5000], [5000, 5000]]
    msg = error(tmp_path, obstacles=_squares(1, L.MAX_OBSTACLE_VERTICES + 1), bounds=wide)
    assert f"obstacles[0]: {L.MAX_OBSTACLE_VERTICES + 1} entries are too many" in msg


def test_too_many_vertices_in_all(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(L, "MAX_TOTAL_VERTICES", 30)
    msg = error(tmp_path, obstacles=_squares(8), bounds=[[-5000, -5000], [5000, 5000]])
    assert "obstacles: 32 obstacle vertices in all are too many; give at most 30" in msg


def test_too_many_faults(tmp_path: Path) -> None:
    msg = error(tmp_path, sim={"faults": [{"kind": "dropout"}] * (L.MAX_FAULTS + 1)})
    assert "sim.faults: " in msg and "too many" in msg


# ------------------------------------------------------------------------------------ physical values


@pytest.mark.parametrize(
    ("section", "key", "value", "limit"),
    [
        ("carrier", "max_speed", L.MAX_SPEED * 1.01, "<= 150"),
        ("carrier", "max_speed", L.MIN_SPEED / 2, ">= 0.01"),
        ("rovers", "max_speed", 1e308, "<= 150"),
        ("carrier", "accel", L.MAX_ACCEL + 1, "<= 200"),
        ("carrier", "turn_rate", L.MAX_TURN_RATE + 1, "<= 100"),
        ("carrier", "unload_time", 1e308, "<= 3600"),
        ("carrier", "load_time", L.MAX_HANDLING_TIME + 1, "<= 3600"),
        ("carrier", "heading_deg", 1e9, "<= 3600"),
        ("carrier", "position", [1e6, 0], "<= 100000"),
        ("rovers", "deploy_range", L.MAX_RANGE * 2, "<= 1e+06"),
        ("rovers", "endurance_range", 1e300, "<= 1e+06"),
        ("links", "heartbeat_timeout", 1e9, "<= 3600"),
        ("sim", "speedup", 1e6, "<= 1000"),
        ("planner", "seed", 2**64, "0..4294967295"),
        ("planner", "roadmap", {"xi1": 1e308}, "<= 1000"),
    ],
)
def test_physical_limits(tmp_path: Path, section: str, key: str, value: Any, limit: str) -> None:
    msg = error(tmp_path, with_(section, **{key: value}))
    assert f"{section}.{key}" in msg and "out of range" in msg and limit in msg


def test_dwell_limit(tmp_path: Path) -> None:
    assert "dwell: " in error(tmp_path, dwell=L.MAX_DWELL * 2)


def test_task_coordinates(tmp_path: Path) -> None:
    d = copy.deepcopy(BASE)
    d["tasks"][0]["position"] = [10, 2e5, 1]
    assert "tasks[0].position[1]" in error(tmp_path, d)


def test_geodetic_task_far_from_the_origin(tmp_path: Path) -> None:
    d = copy.deepcopy(BASE)
    d["origin"] = {"lat": 47.0, "lon": 8.0, "alt": 400.0}
    d["tasks"][0] = {"id": "a", "lat": 48.0, "lon": 8.0}  # 111 km north
    assert "tasks[0].lat: lat/lon/alt lie" in error(tmp_path, d)


def test_origin_altitude(tmp_path: Path) -> None:
    msg = error(tmp_path, origin={"lat": 1, "lon": 2, "alt": 1e7})
    assert "origin.alt" in msg and "<= 20000" in msg


def test_energy_derived_range(tmp_path: Path) -> None:
    d = with_("rovers", deploy_range=None, energy={"initial": 1e9, "task": 0, "rho": 1e9})
    msg = error(tmp_path, d)
    assert "rovers.energy: the deploy range" in msg and "change rho, initial or task" in msg


def test_fault_limits(tmp_path: Path) -> None:
    msg = error(tmp_path, sim={"faults": [{"kind": "latency", "seconds": 1e9}]})
    assert "sim.faults[0].seconds" in msg and "<= 60" in msg
    msg = error(tmp_path, sim={"faults": [{"kind": "dropout", "at": 1e300}]})
    assert "sim.faults[0].at" in msg


# ------------------------------------------------------------------------------------ roadmap


def _roadmap(**roadmap: Any) -> dict[str, Any]:
    d = copy.deepcopy(BASE)
    d["obstacles"] = [[[20, 20], [25, 20], [25, 25]]]
    d["bounds"] = [[-10, -10], [90, 90]]
    d["planner"] = {"deploy": "lee-graph", "roadmap": roadmap} if roadmap else {"deploy": "lee-graph"}
    return d


def test_roadmap_nodes(tmp_path: Path) -> None:
    msg = error(tmp_path, _roadmap(xi1=256))
    assert "planner.roadmap: the global roadmap would have 25750 nodes" in msg
    assert "lower planner.roadmap.xi1" in msg
    msg = error(tmp_path, _roadmap(xi3=100))
    assert "local roadmap" in msg


def test_roadmap_edges(tmp_path: Path) -> None:
    d = _roadmap(xi1=10)
    d["rovers"]["deploy_range"] = 1e5
    assert "edges" in error(tmp_path, d)


def test_roadmap_with_huge_bounds(tmp_path: Path) -> None:
    d = _roadmap()
    d["bounds"] = [[-1e5, -1e5], [1e5, 1e5]]
    assert "bounds: the global roadmap would have" in error(tmp_path, d)


def test_roadmap_defaults_are_within_the_budget(tmp_path: Path) -> None:
    assert load(tmp_path, _roadmap()).obstacles


# ------------------------------------------------------------------------------------ mqtt


def test_accept_task_changes(tmp_path: Path) -> None:
    assert load(tmp_path, mqtt={"url": "mqtt://localhost"}).mqtt.accept_task_changes is False
    on = load(tmp_path, mqtt={"url": "mqtt://localhost", "accept_task_changes": True})
    assert on.mqtt is not None and on.mqtt.accept_task_changes is True
    msg = error(tmp_path, mqtt={"url": "mqtt://localhost", "accept_task_changes": "yes please"})
    assert "mqtt.accept_task_changes: expected true or false" in msg


def test_pure_python_parser_fallback_has_the_same_limits(monkeypatch: pytest.MonkeyPatch) -> None:
    import fleetctl.mission.yaml_safe as ys

    monkeypatch.setattr(ys, "_CParser", None)
    assert read_yaml("a: &x [1, 2]\nb: *x\n")[0] == {"a": [1, 2], "b": [1, 2]}
    with pytest.raises(YamlError, match="recursive alias"):
        read_yaml("zz: &r [1, *r]\n")
    with pytest.raises(YamlError, match="nested more than"):
        read_yaml("[" * 5000 + "]" * 5000)


def test_planner_refuses_a_dense_roadmap_it_was_not_protected_from() -> None:
    """planners.roadmap.graph's own guard: edges counted before they are built (pure maths, no loader)."""
    import numpy as np

    from planners.core.problem import PlanningError
    from planners.roadmap.graph import MAX_EDGES, Roadmap, Workspace

    ws = Workspace([], ((0.0, 0.0), (10.0, 10.0)))
    pts = np.random.default_rng(0).uniform(0, 10, size=(600, 2))
    with pytest.raises(PlanningError, match=f"more than {MAX_EDGES}"):
        Roadmap(ws, pts, 100.0)  # complete graph: ~180,000 edges
    assert Roadmap(ws, pts[:100], 100.0).n_edges == 100 * 99 // 2
