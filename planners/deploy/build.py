"""A deployment plan from clusters and stops: the rovers leave the deck in order, timed by the
time model."""

from __future__ import annotations

import math
from collections.abc import Sequence

from planners.core.plan import SNAP, Plan, RoverLeg, Stop
from planners.core.problem import DeployProblem, Point2, Vec3
from planners.core.timing import RANGE_MARGIN, retime


def build_plan(problem: DeployProblem, planner: str, clusters: Sequence[Sequence[int]],
               positions: Sequence[Point2], compute_ms: float = 0.0) -> Plan:
    """Turn clusters and stops into a timed Plan; rovers leave the deck in order."""
    rover_ids = iter(problem.rover_ids())
    stops: list[Stop] = []
    prev: Vec3 = problem.start
    for members, pos in zip(clusters, positions, strict=True):
        here: Vec3 = (pos[0], pos[1], 0.0)
        reach = problem.deploy_range - RANGE_MARGIN
        if 0.0 < math.dist(prev, here) < SNAP and all(
                math.dist(prev, problem.tasks[i].position) <= reach for i in members):
            # a hop of millimetres has an arbitrary heading once coordinates are rounded for JSON,
            # and turning to it costs real time: stay where the carrier is
            here = prev
        legs = [RoverLeg(rover=next(rover_ids), task=problem.tasks[i].id,
                         path=[here, problem.tasks[i].position]) for i in members]
        stops.append(Stop(position=here, carrier_path=[prev, here], rovers=legs))
        prev = here
    plan = Plan(kind="deploy", planner=planner, start=problem.start, heading=problem.heading, stops=stops,
                compute_ms=compute_ms)
    return retime(plan, problem.carrier, problem.rover)
