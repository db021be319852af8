"""The mission keys of a long operation: ``operation``, ``tasks[].duration``,
``tasks[].work``, ``rovers.work``, ``carrier.swap_time``; existing missions keep their meaning;
``fleetctl plan`` plans an operation mission and the independent checker accepts the plan."""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from fleetctl.cli import main
from fleetctl.mission import Mission, MissionError, load_mission, parse_mission
from planners.core.problem import Task
from planners.operations import OpTask
from tests.operation_checker import OpSpec, check_operation

ROOT = Path(__file__).resolve().parents[2]
OPERATION = ROOT / "missions" / "operation.yaml"
RAW = yaml.safe_load(OPERATION.read_text())


def _parse(d: dict[str, Any]) -> Mission:
    return parse_mission(d, "m.yaml")


def _changed(**top: Any) -> dict[str, Any]:
    d = copy.deepcopy(RAW)
    d.update(top)
    return d


def test_existing_missions_keep_their_meaning() -> None:
    m = load_mission(ROOT / "missions" / "recon.yaml")
    assert not m.operation and m.carrier.swap_time == 0.0
    assert [m.task_work(t.id).duration for t in m.tasks] == [m.dwell] * len(m.tasks)
    assert not any(m.task_work(t.id).ground for t in m.tasks)


def test_fewer_rovers_than_tasks_only_in_an_operation() -> None:
    refused = r"rovers\.fleet\.count: only 6 rover\(s\) for 18 tasks.*operation: true"
    with pytest.raises(MissionError, match=refused):
        _parse(_changed(operation=False))
    assert len(_parse(RAW).rovers.units) == 6


def test_durations_default_to_dwell_and_work_to_rovers_work() -> None:
    m = load_mission(OPERATION)
    tasks = {t.id: t for t in m.operation_problem().tasks}
    assert tasks["t4"].duration == m.dwell == 120.0  # no duration given
    assert tasks["t1"].duration == 240.0 and not tasks["t1"].ground  # rovers.work: hover
    assert tasks["t9"].ground and tasks["t9"].duration == 300.0  # work: ground
    assert m.operation_problem().swap_time == 30.0
    landed = copy.deepcopy(RAW)
    landed["rovers"]["work"] = "ground"
    assert all(t.ground for t in _parse(landed).operation_problem().tasks)
    added = dataclasses.replace(m, tasks=(*m.tasks, Task("new", (0.0, 50.0, 2.0))))  # e.g. over MQTT
    assert added.operation_problem().tasks[-1] == OpTask("new", (0.0, 50.0, 2.0), m.dwell, False)


@pytest.mark.parametrize("path, value, message", [
    (("tasks", 0, "duration"), -1, r"tasks\[0\]\.duration: -1 is out of range"),
    (("tasks", 0, "duration"), "long", r"tasks\[0\]\.duration: expected a number"),
    (("tasks", 0, "work"), "hovering", r"tasks\[0\]\.work: .*did you mean 'hover'"),
    (("rovers", "work"), "air", r"rovers\.work: .*use one of: hover, ground"),
    (("carrier", "swap_time"), -3, r"carrier\.swap_time: -3 is out of range"),
    (("operation",), "yes", r"operation: expected true or false"),
])
def test_bad_values_are_refused_with_the_key(path: tuple[Any, ...], value: Any, message: str) -> None:
    d = copy.deepcopy(RAW)
    node: Any = d
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(MissionError, match=message):
        _parse(d)


def test_a_hovered_task_longer_than_a_battery_is_refused() -> None:
    d = copy.deepcopy(RAW)
    d["tasks"][0]["duration"] = 600  # the battery gives 540 s above the reserve
    with pytest.raises(MissionError, match=r"tasks\[0\]\.duration: task 't1' needs 600 s of work hovering"):
        _parse(d)
    d["tasks"][0]["work"] = "ground"  # landed it costs no battery
    assert _parse(d).operation_problem().tasks[0].duration == 600


def test_an_operation_has_one_carrier() -> None:
    d = copy.deepcopy(RAW)
    car = d.pop("carrier")
    fleet = d["rovers"].pop("fleet")
    d["carriers"] = [{**car, "fleet": fleet}, {**car, "id": "c2", "sysid": 2, "fleet": {"count": 2}}]
    with pytest.raises(MissionError, match=r"operation: a long operation is planned for one carrier"):
        _parse(d)


def _spec(m: Mission) -> OpSpec:
    c, r = m.carrier, m.rovers
    tasks = {t.id: (t.position, m.task_work(t.id).duration, m.task_work(t.id).ground) for t in m.tasks}
    return OpSpec(c.max_speed, c.accel, c.turn_rate, c.unload_time, c.load_time, r.takeoff_time,
                  r.land_time, r.max_speed, r.accel, r.deploy_range, r.endurance_range / r.max_speed,
                  r.reserve, c.swap_time, 1.0, 3.0, tasks, r.ids)


@pytest.mark.parametrize("planner", ["operation", "waves"])
def test_plan_an_operation_mission(planner: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--mission", str(OPERATION), "--planner", planner, "--json"]) == 0
    plan = json.loads(capsys.readouterr().out)
    assert plan["kind"] == "operation" and plan["planner"] == planner
    check_operation(plan, _spec(load_mission(OPERATION)))
    assert len(plan["sorties"]) > 6 > 0  # more sorties than rovers: rovers fly again
    if planner == "operation":  # launches and pick-ups interleaved on one route, tasks chained
        assert any(s["pickups"] and s["launches"] for s in plan["stops"])
        assert any(len(s["visits"]) > 1 for s in plan["sorties"])


def test_plan_summary_and_deploy_or_collect_alone_refuse_an_operation(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--mission", str(OPERATION)]) == 0
    assert "operation ends" in capsys.readouterr().out
    assert main(["plan", "--mission", str(OPERATION), "--collect"]) == 2
    for command in ("deploy", "collect"):
        assert main([command, "--mission", str(OPERATION), "--headless"]) == 2
        assert f"fly it with 'fleetctl run --mission {OPERATION}'" in capsys.readouterr().err
