"""The search after the greedy of ``lee-graph`` (planners/roadmap/search.py, route.py, costs.py):
never slower than Algorithm 6.3's plan, every stop a roadmap node clear of the obstacles, every
flight within range and every time recomputed by the independent checker (tests/plan_checker.py
through tests/planners/test_roadmap.py's checks)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

import planners.roadmap.costs as costs_module
import planners.roadmap.search as search_module
from fleetctl.mission import load_mission
from planners.core.moves import MOVES, SMALL_MOVES
from planners.core.plan import Plan
from planners.core.problem import CollectProblem, CollectRover, DeployProblem, PlanningError, Task
from planners.core.timing import dissertation_model
from planners.roadmap.collect import _Collect, build_collect_graph_plan, plan_collect_lee_graph
from planners.roadmap.costs import RoadmapCosts
from planners.roadmap.deploy import _Deploy, build_graph_plan, plan_lee_graph
from planners.roadmap.route import RouteSpace
from planners.roadmap.search import improve
from tests.planners.test_roadmap import CARRIER, ROVER, check_collect, check_deploy, random_map

ROOT = Path(__file__).resolve().parents[2]
BOUNDS = ((0.0, 0.0), (60.0, 60.0))


def deploy_problem(seed: int, n: int = 6, **kw: object) -> tuple[DeployProblem, list]:
    obstacles, tasks, start = random_map(seed, n)
    p = DeployProblem(CARRIER, ROVER, 10.0, (*start, 0.0), 0.3,
                      tuple(Task(f"t{i + 1}", t) for i, t in enumerate(tasks)),
                      obstacles=tuple(obstacles), bounds=BOUNDS, seed=seed)
    return dataclasses.replace(p, **kw), obstacles


def collect_problem(seed: int, n: int = 6, **kw: object) -> tuple[CollectProblem, list]:
    obstacles, tasks, start = random_map(seed, n)
    rovers = tuple(CollectRover(f"r{i + 1}", t, 25.0) for i, t in enumerate(tasks))
    p = CollectProblem(CARRIER, ROVER, (*start, 0.0), 0.3, rovers, obstacles=tuple(obstacles), bounds=BOUNDS,
                       seed=seed)
    return dataclasses.replace(p, **kw), obstacles


def stops_on_roadmap(plan: Plan, obstacles: list) -> None:
    """Every stop is a node of the plan's roadmap, outside every obstacle."""
    xy = plan.roadmap.xy
    polys = [Polygon(p) for p in obstacles]
    for s in plan.stops:
        assert np.min(np.hypot(xy[:, 0] - s.position[0], xy[:, 1] - s.position[1])) == 0.0
        assert not any(poly.intersects(Point(s.position[:2])) for poly in polys)


def planned(fn, problem):  # type: ignore[no-untyped-def]
    try:
        return fn(problem)
    except PlanningError as e:  # a random wall may enclose a target: the error names it
        assert "cannot be reached" in str(e)
        return None


@pytest.mark.parametrize("seed", range(8))
def test_deploy_search_never_slower_than_the_greedy(seed: int) -> None:
    problem, obstacles = deploy_problem(seed)
    greedy = planned(lambda p: plan_lee_graph(p, search=False), problem)
    if greedy is None:
        return
    plan = plan_lee_graph(problem)
    assert plan.makespan <= greedy.makespan + 1e-9
    check_deploy(plan, problem, obstacles)  # times recomputed, ranges, every task once, walls
    stops_on_roadmap(plan, obstacles)


@pytest.mark.parametrize("seed", range(8))
def test_collect_search_never_slower_than_the_greedy(seed: int) -> None:
    problem, obstacles = collect_problem(seed)
    greedy = planned(lambda p: plan_collect_lee_graph(p, search=False), problem)
    if greedy is None:
        return
    plan = plan_collect_lee_graph(problem)
    assert plan.makespan <= greedy.makespan + 1e-9
    check_collect(plan, problem, obstacles)
    stops_on_roadmap(plan, obstacles)


def test_the_search_gains_on_the_paper_maps() -> None:
    """Table 6.2's open map: the moves and the polish reach open-space ``lee``'s plan (27.968 s
    today; Algorithm 6.3 alone 28.135 s); among the office walls the search is faster too."""
    outdoor = dissertation_model(load_mission(ROOT / "missions/paper/roadmap_outdoor.yaml").deploy_problem())
    assert plan_lee_graph(outdoor).makespan <= 27.965
    office = load_mission(ROOT / "missions/paper/roadmap_office.yaml")
    for fn, p in ((plan_lee_graph, dissertation_model(office.deploy_problem())),
                  (plan_collect_lee_graph, dissertation_model(office.collect_problem()))):
        assert fn(p).makespan < fn(p, search=False).makespan - 0.05


def test_route_times_are_the_plans() -> None:
    """The route's incremental times (``replace`` of every move, ``moved``) equal a fresh timing and
    the built plan's ``retime``: one time model."""
    problem, _ = deploy_problem(3, 7)
    dep = _Deploy(problem, True)
    order = dep.run()
    space = RouteSpace(RoadmapCosts(dep.w, problem.carrier, problem.rover, True), problem.heading, True)
    route = space.timed([list(m) for _, m in order], [n for n, _ in order], None, 0)
    assert route.makespan == pytest.approx(build_graph_plan(problem, dep.w, order).makespan, abs=1e-9)
    tried = 0
    for move in SMALL_MOVES:
        for change in list(move(route.clusters, space.fits, 0))[:6]:
            t, cand = route.replace(*change)
            fresh = space.timed(cand.clusters, cand.nodes, None, 0)
            assert t == pytest.approx(fresh.makespan, abs=1e-9)
            plan = build_graph_plan(problem, dep.w, cand.order())
            assert t == pytest.approx(plan.makespan, abs=1e-6)
            tried += 1
    assert tried > 10
    polished = space.polish(route)
    assert polished.makespan <= route.makespan
    assert polished.makespan == pytest.approx(build_graph_plan(problem, dep.w, polished.order()).makespan,
                                              abs=1e-6)


def test_collect_route_times_are_the_plans() -> None:
    problem, _ = collect_problem(5, 7)
    col = _Collect(problem, True)
    order = col.run()
    space = RouteSpace(RoadmapCosts(col.w, problem.carrier, problem.rover, False), problem.heading, False)
    route = space.timed([list(m) for _, m in order], [n for n, _ in order], None, 0)
    assert route.makespan == pytest.approx(build_collect_graph_plan(problem, col.w, order).makespan, abs=1e-9)
    best = improve(route)
    assert best.makespan <= route.makespan
    assert best.makespan == pytest.approx(build_collect_graph_plan(problem, col.w, best.order()).makespan,
                                          abs=1e-6)
    for members in best.clusters:  # every stop serves its cluster (the greedy's rule)
        assert space.fits(members)
    assert all(move in SMALL_MOVES for move in MOVES)


@pytest.mark.parametrize("deploy", [True, False])
def test_the_polish_bounds_never_exceed_the_time_they_bound(deploy: bool) -> None:
    """The polish skips a node when a lower bound on the route through it is no faster than the
    route (``scores(low=True)``, ``bound_through``): the bounds must hold, turns included."""
    problem, _ = deploy_problem(4, 7) if deploy else collect_problem(4, 7)
    world = _Deploy(problem, True) if deploy else _Collect(problem, True)
    order = world.run()
    space = RouteSpace(RoadmapCosts(world.w, problem.carrier, problem.rover, deploy), problem.heading, deploy)
    route = space.timed([list(m) for _, m in order], [n for n, _ in order], None, 0)
    assert problem.carrier.turn_rate is not None
    checked = 0
    for k, members in enumerate(route.clusters):
        prev, clock, _, _ = route.state_before(k)
        last = k + 1 == len(route.clusters)
        nxt, tail, ready = (None, 0.0, 0.0) if last else (
            route.nodes[k + 1], route.tail(k + 1), route.done[k + 1])
        nodes, low = space.scores(members, prev, clock, nxt, tail, ready, low=True)
        for j in range(0, len(nodes), max(len(nodes) // 12, 1)):
            t = route.moved(k, int(nodes[j])).makespan
            assert low[j] <= t + 1e-9
            assert space.bound_through(route, k, int(nodes[j]), j) <= t + 1e-9
            checked += 1
    assert checked > 8


def test_same_seed_same_searched_plan() -> None:
    for problem in (deploy_problem(2)[0], collect_problem(2)[0]):
        fn = plan_lee_graph if isinstance(problem, DeployProblem) else plan_collect_lee_graph
        a, b = fn(problem).to_json(), fn(problem).to_json()
        a.pop("compute_ms"), b.pop("compute_ms")
        assert a == b


def test_a_spent_budget_gives_the_quick_plan() -> None:
    """budget_ms = 0: the deadline has passed when the search starts, so no anytime search runs:
    the plan is the quick plan (deterministic), no slower than Algorithm 6.3's."""
    for seed in (1, 4):
        problem, obstacles = deploy_problem(seed, budget_ms=0.0)
        greedy = planned(lambda p: plan_lee_graph(p, search=False), problem)
        if greedy is None:
            continue
        a, b = plan_lee_graph(problem), plan_lee_graph(dataclasses.replace(problem, budget_ms=None))
        assert a.makespan <= greedy.makespan + 1e-9
        ja, jb = a.to_json(), b.to_json()
        ja.pop("compute_ms"), jb.pop("compute_ms")
        assert ja == jb
        check_deploy(a, problem, obstacles)


class _PollBudget:
    """A budget's deadline counted in polls of ``stop()`` instead of seconds: the search it bounds
    does the same work on any machine."""

    def __init__(self, polls: int) -> None:
        self.limit, self.polls = polls, 0

    def __call__(self) -> bool:
        self.polls += 1
        return self.polls > self.limit


def test_a_budget_runs_the_anytime_search(monkeypatch: pytest.MonkeyPatch) -> None:
    """With a budget the iterated search runs, is bounded by the budget's deadline, and keeps only
    improvements: what it returns is never slower than the route it started from, and the plan is
    never slower than the quick plan. The deadline is a count of polls, so nothing here depends on
    how fast the machine is."""
    problem, obstacles = collect_problem(6)
    quick = plan_collect_lee_graph(problem)
    budget = _PollBudget(60)
    monkeypatch.setattr(search_module, "deadline",
                        lambda budget_ms, t0=None: None if budget_ms is None else budget)
    runs: list[tuple[float, float, bool]] = []  # (start makespan, result makespan, the budget spent)
    real = search_module.iterated_search

    def spy(best, fits, rebuild, finish, rng, stop, max_fails):  # type: ignore[no-untyped-def]
        assert stop is budget  # bounded by the budget's deadline
        better = real(best, fits, rebuild, finish, rng, stop, max_fails)
        runs.append((best.makespan, better.makespan, budget.polls > budget.limit))
        return better

    monkeypatch.setattr(search_module, "iterated_search", spy)
    plan = plan_collect_lee_graph(dataclasses.replace(problem, budget_ms=1.0))
    assert len(runs) == 1, "the budget did not run the iterated search"
    start, result, spent = runs[0]
    assert spent, "the iterated search ended before its budget (or it did not poll the deadline)"
    assert result <= start + 1e-9  # only improvements kept
    assert plan.makespan <= quick.makespan + 1e-9
    check_collect(plan, problem, obstacles)


def test_tiny_caches_give_the_same_plan(monkeypatch: pytest.MonkeyPatch) -> None:
    """The memoised roadmap costs are bounded: emptied when full, they are computed again alike."""
    problem, _ = deploy_problem(7, 5)
    want = plan_lee_graph(problem).to_json()
    for name in ("PAIRS", "ROWS", "CLUSTERS"):
        monkeypatch.setattr(costs_module, name, 3)
    got = plan_lee_graph(problem).to_json()
    want.pop("compute_ms"), got.pop("compute_ms")
    assert got == want
