"""Deployment baselines: ``greedy2opt`` (ch. 4.6.2's comparison) and ``direct``."""



from __future__ import annotations

import time

import numpy as np

from planners.core.plan import Plan
from planners.core.problem import DeployProblem, PlanningError, refuse_obstacles
from planners.core.routing import two_opt_route  # noqa: F401  (re-exported for collection)
from planners.deploy.build import build_plan


def plan_greedy2opt(problem: DeployProblem) -> Plan:
    """The carrier drives a nearest-neighbour + 2-opt route over every task's ground point and
    unloads one rover under each task (the comparison of ch. 4.6.2)."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "greedy2opt")
    _check_fleet(problem)
    pts = np.array([[t.position[0], t.position[1]] for t in problem.tasks], dtype=float)
    order = two_opt_route(pts, np.array(problem.start[:2], dtype=float))
    clusters = [[i] for i in order]
    positions = [(float(pts[i][0]), float(pts[i][1])) for i in order]
    return build_plan(problem, "greedy2opt", clusters, positions, (time.perf_counter() - t0) * 1e3)


def plan_direct(problem: DeployProblem) -> Plan:
    """Every rover leaves from the carrier's start, which does not move."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "direct")
    _check_fleet(problem)
    x, y = problem.start[0], problem.start[1]
    far = [t.id for t in problem.tasks
           if np.linalg.norm(np.subtract(t.position, (x, y, 0.0))) > problem.deploy_range]
    if far:
        raise PlanningError(
            f"planner 'direct' cannot serve {', '.join(far)}: farther than the deploy range of "
            f"{problem.deploy_range:g} m from the carrier's start; use --planner lee")
    clusters = [list(range(len(problem.tasks)))] if problem.tasks else []
    return build_plan(problem, "direct", clusters, [(x, y)] * len(clusters), (time.perf_counter() - t0) * 1e3)


def _check_fleet(problem: DeployProblem) -> None:
    if len(problem.rover_ids()) < len(problem.tasks):
        raise PlanningError(f"{len(problem.tasks)} tasks need as many rovers, only "
                            f"{len(problem.rover_ids())} on the carrier")
    for t in problem.tasks:
        if not 0.0 <= t.position[2] <= problem.deploy_range:
            raise PlanningError(f"task {t.id} at height {t.position[2]:g} m is out of the deploy range "
                                f"of {problem.deploy_range:g} m")
