"""Deployment and collection among obstacles (dissertation ch. 6, planner ``lee-graph``)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import LineString, Point, Polygon

from fleetctl.cli import main
from fleetctl.mission import Mission, load_mission
from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS
from planners.core.problem import (
    CarrierSpec,
    CollectProblem,
    CollectRover,
    DeployProblem,
    Motion,
    PlanningError,
    Task,
)
from planners.roadmap.collect import plan_collect_lee_graph
from planners.roadmap.deploy import plan_lee_graph
from planners.roadmap.graph import Roadmap, Workspace
from tests.plan_checker import check_plan

ROOT = Path(__file__).resolve().parents[2]
MISSIONS = sorted((ROOT / "missions" / "paper").glob("roadmap_*.yaml"))


def _carrier(m: Mission) -> dict:
    c = m.carrier
    return {"max_speed": c.max_speed, "accel": c.accel, "turn_rate": c.turn_rate,
            "unload_time": c.unload_time, "load_time": c.load_time}


def _rover(motion: Motion) -> dict:
    return {"max_speed": motion.max_speed, "accel": motion.accel, "fixed_time": motion.fixed_time}


def assert_outside(plan: dict, obstacles) -> None:
    """No carrier or rover segment's ground projection enters an obstacle's interior."""
    polys = [Polygon(p) for p in obstacles]
    for stop in plan["stops"]:
        paths = [stop["carrier_path"]] + [r["path"] for r in stop["rovers"]]
        for path in paths:
            for p, q in zip(path, path[1:], strict=False):
                seg = LineString([p[:2], q[:2]]) if p[:2] != q[:2] else Point(p[:2])
                for k, poly in enumerate(polys):
                    assert not seg.intersects(poly) or seg.touches(poly), (p, q, k)


def check_deploy(plan, problem: DeployProblem, obstacles) -> None:
    js = plan.to_json()
    carrier = {"max_speed": problem.carrier.max_speed, "accel": problem.carrier.accel,
               "turn_rate": problem.carrier.turn_rate, "unload_time": problem.carrier.unload_time,
               "load_time": problem.carrier.load_time, "takeoff_time": problem.carrier.takeoff_time,
               "land_time": problem.carrier.land_time, "vertex_stops": problem.carrier.vertex_stops}
    makespan = check_plan(js, carrier, _rover(problem.rover), problem.deploy_range)
    assert makespan == pytest.approx(plan.makespan, abs=1e-4)
    served = [r["task"] for s in js["stops"] for r in s["rovers"]]
    assert sorted(served) == sorted(t.id for t in problem.tasks)  # every task once
    rovers = [r["rover"] for s in js["stops"] for r in s["rovers"]]
    assert len(set(rovers)) == len(rovers)
    assert_outside(js, obstacles)


def check_collect(plan, problem: CollectProblem, obstacles) -> None:
    js = plan.to_json()
    carrier = {"max_speed": problem.carrier.max_speed, "accel": problem.carrier.accel,
               "turn_rate": problem.carrier.turn_rate, "unload_time": problem.carrier.unload_time,
               "load_time": problem.carrier.load_time, "takeoff_time": problem.carrier.takeoff_time,
               "land_time": problem.carrier.land_time, "vertex_stops": problem.carrier.vertex_stops}
    ranges = {r.id: r.range for r in problem.rovers}
    starts = {r.id: list(r.position) for r in problem.rovers}
    makespan = check_plan(js, carrier, _rover(problem.rover), ranges, starts)
    assert makespan == pytest.approx(plan.makespan, abs=1e-4)
    got = sorted(r["rover"] for s in js["stops"] for r in s["rovers"])
    assert got == sorted(ranges)  # every rover collected once
    assert_outside(js, obstacles)


# ----------------------------------------------------------------------------- the four missions


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.stem)
def test_paper_missions_deploy(path: Path) -> None:
    m = load_mission(path)
    problem = m.deploy_problem()
    assert problem.bounds == m.bounds and problem.obstacles == m.obstacles
    plan = DEPLOY_PLANNERS["lee-graph"](problem)
    check_deploy(plan, problem, m.obstacles)
    assert plan.roadmap is not None and plan.roadmap.global_nodes <= plan.roadmap.n_nodes


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.stem)
def test_paper_missions_collect(path: Path) -> None:
    m = load_mission(path)
    problem = m.collect_problem()
    plan = COLLECT_PLANNERS["lee-graph"](problem)
    check_collect(plan, problem, m.obstacles)


def test_table_6_2_mission_is_the_dissertations() -> None:
    m = load_mission(ROOT / "missions" / "paper" / "roadmap_outdoor.yaml")
    assert [t.position[:2] for t in m.tasks] == [(23, 27), (80, 20), (90, 25), (85, 30), (70, 71), (60, 75),
                                                 (57, 65), (23, 55)]
    assert m.carrier.position[:2] == (27, 13) and m.rovers.deploy_range == 15.0
    # eq. 6.5: 100 m x 100 m, xi1 = 1.5, xi2 = 150 -> Table 6.1's 300 nodes
    plan = plan_lee_graph(m.deploy_problem(), local_prm=False, search=False)  # Algorithm 6.3 alone
    assert plan.roadmap.n_nodes - plan.roadmap.global_nodes <= 10  # only ch. 4's deterministic points
    assert plan.roadmap.global_nodes == 300


def test_cli_plan_json_and_plot(tmp_path: Path, capsys) -> None:
    mission = ROOT / "missions" / "paper" / "roadmap_office.yaml"
    out = tmp_path / "office.png"
    assert main(["plan", "--mission", str(mission), "--json", "--plot", str(out)]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["planner"] == "lee-graph" and out.stat().st_size > 0
    assert any(len(s["carrier_path"]) > 2 for s in js["stops"])  # it does go around walls


def test_cli_picks_lee_graph_for_obstacles_without_a_planner(tmp_path: Path, capsys) -> None:
    text = (ROOT / "missions" / "paper" / "roadmap_office.yaml").read_text()
    text = text.replace("planner: {deploy: lee-graph, collect: lee-graph, seed: 0}", "")
    f = tmp_path / "office.yaml"
    f.write_text(text)
    assert main(["plan", "--mission", str(f), "--json"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["planner"] == "lee-graph" and "using lee-graph" in cap.err


@pytest.mark.parametrize("name", ["lee", "greedy2opt", "direct", "two-task"])
def test_open_space_deploy_planners_refuse_obstacles(name: str) -> None:
    problem = load_mission(ROOT / "missions" / "paper" / "roadmap_office.yaml").deploy_problem()
    with pytest.raises(PlanningError, match="lee-graph"):
        DEPLOY_PLANNERS[name](problem)


@pytest.mark.parametrize("name", ["lee", "lee-convex", "visit-all", "gather"])
def test_open_space_collect_planners_refuse_obstacles(name: str) -> None:
    problem = load_mission(ROOT / "missions" / "paper" / "roadmap_office.yaml").collect_problem()
    with pytest.raises(PlanningError, match="lee-graph"):
        COLLECT_PLANNERS[name](problem)


# ----------------------------------------------------------------------------- random obstacle maps

CARRIER = CarrierSpec(max_speed=8.0, accel=4.0, turn_rate=2.0, unload_time=2.0, load_time=2.0)
ROVER = Motion(3.0, 3.0)


def random_map(seed: int, n_tasks: int = 7) -> tuple[list, list, tuple]:
    """Rectangles and thin walls in a 60 m x 60 m square; tasks (with heights) and a start outside."""
    rng = np.random.default_rng(seed)
    obstacles = []
    for _ in range(rng.integers(3, 8)):
        x, y = rng.uniform(0, 55, 2)
        if rng.random() < 0.5:
            w, h = rng.uniform(2, 12, 2)
        else:  # a thin wall
            w, h = (rng.uniform(8, 25), 0.3) if rng.random() < 0.5 else (0.3, rng.uniform(8, 25))
        obstacles.append(((x, y), (x + w, y), (x + w, y + h), (x, y + h)))
    polys = [Polygon(p) for p in obstacles]

    def free_point() -> tuple[float, float]:
        while True:
            p = tuple(float(c) for c in rng.uniform(1, 59, 2))
            if not any(poly.buffer(0.5).contains(Point(p)) for poly in polys):
                return p

    tasks = [(*free_point(), float(rng.uniform(0, 4))) for _ in range(n_tasks)]
    return obstacles, tasks, free_point()


@pytest.mark.parametrize("seed", range(12))
def test_random_maps_deploy_and_collect(seed: int) -> None:
    obstacles, tasks, start = random_map(seed)
    bounds = ((0.0, 0.0), (60.0, 60.0))
    problem = DeployProblem(CARRIER, ROVER, 10.0, (*start, 0.0), 0.3,
                            tuple(Task(f"t{i + 1}", p) for i, p in enumerate(tasks)),
                            obstacles=tuple(obstacles), bounds=bounds, seed=seed)
    try:
        plan = plan_lee_graph(problem)
    except PlanningError as e:  # a random wall may enclose a task: then the error names it
        assert "cannot be reached" in str(e) and any(f"t{i + 1}" in str(e) for i in range(len(tasks)))
        return
    check_deploy(plan, problem, obstacles)
    rovers = tuple(CollectRover(f"r{i + 1}", p, 25.0) for i, p in enumerate(tasks))
    cp = CollectProblem(CARRIER, ROVER, (*start, 0.0), 0.3, rovers, obstacles=tuple(obstacles), bounds=bounds,
                        seed=seed)
    check_collect(plan_collect_lee_graph(cp), cp, obstacles)


def office_problem() -> DeployProblem:
    return load_mission(ROOT / "missions" / "paper" / "roadmap_office.yaml").deploy_problem()


def test_same_seed_same_plan_and_seed_is_used() -> None:
    p = office_problem()
    a, b = plan_lee_graph(p).to_json(), plan_lee_graph(p).to_json()
    a.pop("compute_ms"), b.pop("compute_ms")
    assert a == b
    r1 = plan_lee_graph(p).roadmap.xy
    r2 = plan_lee_graph(dataclasses.replace(p, seed=p.seed + 1)).roadmap.xy
    assert r1.shape != r2.shape or not np.allclose(r1, r2)


def test_walled_in_task_is_named() -> None:
    p = office_problem()
    box = (((16.0, 1.0), (26.0, 1.0), (26.0, 1.4), (16.0, 1.4)),  # a closed room around t3 (21, 4)
           ((16.0, 7.0), (26.0, 7.0), (26.0, 7.4), (16.0, 7.4)),
           ((16.0, 1.0), (16.4, 1.0), (16.4, 7.4), (16.0, 7.4)),
           ((25.6, 1.0), (26.0, 1.0), (26.0, 7.4), (25.6, 7.4)))
    with pytest.raises(PlanningError, match=r"task t3 cannot be reached from the carrier start"):
        plan_lee_graph(dataclasses.replace(p, obstacles=p.obstacles + box))
    rovers = tuple(CollectRover(f"r{i + 1}", t.position, 30.0) for i, t in enumerate(p.tasks))
    cp = CollectProblem(p.carrier, p.rover, p.start, p.heading, rovers, obstacles=p.obstacles + box,
                        bounds=p.bounds)
    with pytest.raises(PlanningError, match=r"rover r3 cannot be reached"):
        plan_collect_lee_graph(cp)


def test_task_inside_an_obstacle_is_named() -> None:
    p = office_problem()
    block = (((20.0, 3.0), (22.0, 3.0), (22.0, 5.0), (20.0, 5.0)),)
    with pytest.raises(PlanningError, match=r"task t3 at \(21, 4\) lies inside an obstacle"):
        plan_lee_graph(dataclasses.replace(p, obstacles=p.obstacles + block))


def test_shortcut_keeps_clear_of_walls() -> None:
    """Algorithm 6.2 drops the zig-zag but never jumps through a wall."""
    ws = Workspace([((4.0, -1.0), (5.0, -1.0), (5.0, 3.0), (4.0, 3.0))], ((-10.0, -10.0), (20.0, 20.0)))
    pts = np.array([(0, 0), (1, 1), (2, 2), (3, 4), (4.5, 5), (6, 4), (7, 1), (8, 0)], dtype=float)
    rm = Roadmap(ws, pts, 4.0)
    path = rm.shortcut(list(range(len(pts))))
    assert path[0] == (0.0, 0.0) and path[-1] == (8.0, 0.0) and 2 < len(path) < len(pts)
    for p, q in zip(path, path[1:], strict=False):
        assert ws.segment_free(p, q)
    assert not ws.segment_free((0, 0), (8, 0))


@pytest.mark.parametrize("seed", range(4))
def test_collision_masks_equal_shapely_intersects(seed: int) -> None:
    """The workspace's tests (tree boxes, then the prepared polygons) give exactly what testing
    each geometry against every obstacle with shapely's ``intersects`` gives, boundaries included:
    segments along an edge, through a corner, of zero length, points on an edge."""
    rng = np.random.default_rng(seed)
    obstacles = [[(10, 10), (20, 10), (20, 20), (10, 20)], [(30, 5), (40, 15), (30, 25)],
                 [(5, 30), (25, 30), (25, 32), (5, 32)]]
    ws = Workspace(obstacles, ((0.0, 0.0), (50.0, 50.0)))
    polys = [Polygon(p) for p in obstacles]
    vertices = np.array([v for p in obstacles for v in p], dtype=float)
    a = np.concatenate([rng.uniform(0, 50, (300, 2)), vertices, [[0.0, 10.0], [15.0, 0.0], [10.0, 5.0]]])
    b = np.concatenate([a[:300] + rng.normal(0, 8, (300, 2)), vertices,  # zero length at corners
                        [[50.0, 10.0], [15.0, 10.0], [10.0, 25.0]]])  # along an edge, to it, on it
    expect = [not any(LineString([p, q] if np.any(p != q) else [p, q + [0, 1e-9]]).intersects(o)
                      for o in polys) for p, q in zip(a, b, strict=True)]
    assert ws.segments_free(a, b).tolist() == expect
    pts = np.concatenate([rng.uniform(0, 50, (300, 2)), vertices, [[15.0, 10.0], [35.0, 10.0]]])
    assert ws.points_free(pts).tolist() == [not any(Point(p).intersects(o) for o in polys) for p in pts]
    assert ws.rect_free((0.0, 0.0), (9.9, 9.9)) and not ws.rect_free((0.0, 0.0), (10.0, 10.0))
    assert ws.fans_free((0.0, 0.0), (1.0, 1.0), np.array([[2.0, 28.0]]))
    assert not ws.fans_free((0.0, 0.0), (1.0, 1.0), np.array([[2.0, 28.0], [15.0, 15.0]]))
