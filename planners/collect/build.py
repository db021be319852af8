"""A collection plan from clusters and collection locations: every rover flies a straight line to its
meeting point, timed by the time model (eq. 5.2)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from planners.collect.reach import Point2
from planners.core.plan import SNAP, Plan, RoverLeg, Stop
from planners.core.problem import CollectProblem, Vec3
from planners.core.timing import retime


def build_collect_plan(problem: CollectProblem, planner: str, clusters: Sequence[Sequence[int]],
                       positions: Sequence[Point2], compute_ms: float = 0.0) -> Plan:
    """Turn clusters and collection locations into a Plan timed by ``timing.retime``: each rover
    flies a straight 3D line from where it is to its meeting point on the ground."""
    stops: list[Stop] = []
    prev: Vec3 = problem.start
    last: Sequence[int] = ()
    for members, pos in zip(clusters, positions, strict=True):
        inside = _within_reach(problem, members, (float(pos[0]), float(pos[1])))
        here: Vec3 = _snap(problem, members, prev, inside)
        if stops and 0.0 < math.dist(prev[:2], here[:2]) < SNAP and _reach(problem, last, here):
            # this stop cannot be put on the previous one (a rover with no range left is met where it
            # is), but the previous one on this one
            stops[-1] = _stop(problem, last, stops[-1].carrier_path[0], here)
            prev = here
        stops.append(_stop(problem, members, prev, here))
        prev, last = here, members
    plan = Plan(kind="collect", planner=planner, start=problem.start, heading=problem.heading, stops=stops,
                compute_ms=compute_ms)
    return retime(plan, problem.carrier, problem.rover)


def _within_reach(problem: CollectProblem, members: Sequence[int], p: Point2) -> Vec3:
    """``p`` pulled inside every member's reach disc where rounding left it a hair outside
    (alternating projections; the discs intersect, so this converges to a point of I_β)."""
    x, y = p
    for _ in range(50):
        worst = 0.0
        for i in members:
            (gx, gy, z), r = problem.rovers[i].position, problem.rovers[i].range
            rho = math.sqrt(max(r * r - z * z, 0.0))
            d = math.hypot(x - gx, y - gy)
            if d > rho:
                worst = max(worst, d - rho)
                if d == 0.0 or rho == 0.0:
                    x, y = gx, gy
                else:
                    x, y = gx + (x - gx) * rho / d, gy + (y - gy) * rho / d
        if worst == 0.0:
            break
    return (x, y, 0.0)


def _snap(problem: CollectProblem, members: Sequence[int], prev: Vec3, here: Vec3) -> Vec3:
    """A stop a hair's breadth (< 1 cm) from the previous one is put exactly on it when every rover
    can still reach it: a hop of micrometres has an arbitrary heading once the plan's coordinates
    are rounded for JSON, and turning to it would cost real time."""
    if 0.0 < math.dist(prev[:2], here[:2]) < SNAP:
        snapped: Vec3 = (prev[0], prev[1], 0.0)
        if _reach(problem, members, snapped):
            return snapped
    return here


def _reach(problem: CollectProblem, members: Sequence[int], p: Vec3) -> bool:
    """Every member can fly to ``p`` within its range (with 10 µm to spare)."""
    return all(math.dist(problem.rovers[i].position, p) <= problem.rovers[i].range - 1e-5 for i in members)


def _stop(problem: CollectProblem, members: Sequence[int], came_from: Vec3, here: Vec3) -> Stop:
    """The stop at ``here`` the carrier drives to from ``came_from``, its members flying straight to it."""
    legs = [RoverLeg(rover=problem.rovers[i].id, path=[problem.rovers[i].position, here]) for i in members]
    return Stop(position=here, carrier_path=[came_from, here], rovers=legs)
