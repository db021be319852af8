"""Deployment baselines: ``greedy2opt`` (ch. 4.6.2's comparison) and ``direct``."""

from __future__ import annotations

import time

import numpy as np

from planners.deploy import build_plan
from planners.plan import Plan
from planners.problem import DeployProblem, PlanningError


def two_opt_route(points: np.ndarray, start: np.ndarray) -> list[int]:
    """Open tour from ``start`` through every point: nearest neighbour, then 2-opt to a local optimum."""
    n = len(points)
    if n == 0:
        return []
    nodes = np.vstack([start[None, :], points])
    dmat = np.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=2)
    # Nearest-neighbour construction from the start (node 0).
    route = [0]
    left = np.ones(n + 1, dtype=bool)
    left[0] = False
    for _ in range(n):
        row = np.where(left, dmat[route[-1]], np.inf)
        nxt = int(np.argmin(row))
        route.append(nxt)
        left[nxt] = False
    # 2-opt on the open path: reverse route[i..j]; the start stays first, the end is free.
    path = np.array(route)
    improved = True
    while improved:
        improved = False
        for i in range(1, n):
            a, b = path[i - 1], path[i]
            js = np.arange(i + 1, n + 1)
            c = path[js]
            d_next = np.append(dmat[c[:-1], path[js[:-1] + 1]], 0.0)  # edge after j (none at the end)
            after = np.append(dmat[b, path[js[:-1] + 1]], 0.0)
            gain = dmat[a, b] + d_next - dmat[a, c] - after
            k = int(np.argmax(gain))
            if gain[k] > 1e-9:
                j = int(js[k])
                path[i: j + 1] = path[i: j + 1][::-1].copy()
                improved = True
    return [int(v) - 1 for v in path[1:]]


def plan_greedy2opt(problem: DeployProblem) -> Plan:
    """The carrier drives a nearest-neighbour + 2-opt route over every task's ground point and
    unloads one rover under each task (the comparison of ch. 4.6.2)."""
    t0 = time.perf_counter()
    _check_fleet(problem)
    pts = np.array([[t.position[0], t.position[1]] for t in problem.tasks], dtype=float)
    order = two_opt_route(pts, np.array(problem.start[:2], dtype=float))
    clusters = [[i] for i in order]
    positions = [(float(pts[i][0]), float(pts[i][1])) for i in order]
    return build_plan(problem, "greedy2opt", clusters, positions, (time.perf_counter() - t0) * 1e3)


def plan_direct(problem: DeployProblem) -> Plan:
    """Every rover leaves from the carrier's start, which does not move."""
    t0 = time.perf_counter()
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
