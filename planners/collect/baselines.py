"""Collection baselines of ch. 5.5.2 (Fig. 5.12): ``visit-all`` and ``gather``.

* ``visit-all``: the rovers land where they are (a rover at height z flies z straight down) and
  the carrier visits every landing point on a nearest-neighbour + 2-opt route (the greedy two-opt
  comparison of ch. 5.6.2);
* ``gather``: every rover flies toward the carrier's start as far as its range allows (ch. 5.5.2's
  "the rovers simply move so that the distance to the carrier's initial location is minimised"),
  then the carrier visits the landing points on a nearest-neighbour + 2-opt route.

Rovers that land on the same point share one stop.
"""

from __future__ import annotations

import math
import time

import numpy as np

from planners.collect.build import build_collect_plan
from planners.collect.instance import CollectInstance
from planners.collect.reach import Point2
from planners.core.plan import Plan
from planners.core.problem import CollectProblem, refuse_obstacles
from planners.core.routing import two_opt_route


def _visit(problem: CollectProblem, planner: str, landing: list[Point2], t0: float) -> Plan:
    """One stop per distinct landing point, in nearest-neighbour + 2-opt order from the start."""
    stops: dict[Point2, list[int]] = {}
    for i, p in enumerate(landing):
        stops.setdefault(p, []).append(i)
    points = list(stops)
    start = np.array(problem.start[:2], dtype=float)
    order = two_opt_route(np.array(points, dtype=float).reshape(-1, 2), start)
    clusters = [stops[points[k]] for k in order]
    positions = [points[k] for k in order]
    return build_collect_plan(problem, planner, clusters, positions, (time.perf_counter() - t0) * 1e3)


def plan_collect_visit_all(problem: CollectProblem) -> Plan:
    """``visit-all``: the carrier visits every rover where it lands."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "visit-all")
    inst = CollectInstance(problem)  # validates the rovers
    return _visit(problem, "visit-all", list(inst.pts2), t0)


def plan_collect_gather(problem: CollectProblem) -> Plan:
    """``gather``: rovers fly toward the carrier's start as far as their range allows first."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "gather")
    inst = CollectInstance(problem)
    sx, sy = problem.start[0], problem.start[1]
    landing: list[Point2] = []
    for (x, y), rho in zip(inst.pts2, inst.radii.tolist(), strict=True):
        d = math.hypot(sx - x, sy - y)
        if d <= rho:
            landing.append((float(sx), float(sy)))
        else:
            landing.append((x + (sx - x) * rho / d, y + (sy - y) * rho / d))
    return _visit(problem, "gather", landing, t0)
