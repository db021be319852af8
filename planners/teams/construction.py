"""The fast construction: share the item groups by the teams' times to them.

Each team keeps an estimated route (an open path from its start through the centres of its
groups, grown by cheapest insertion) whose time is the sum of ``timing.leg_time`` over its hops
plus one stop time (unload and take-off, or touch-down and load) per stop. Groups farthest from
every start go first; each goes to the team whose estimate then makes the largest estimate
smallest (ties: the smallest increase), within the team's deck. A group no team has room for is
handed out item by item. The exact time model scores the result afterwards
(``planners.teams.allocation``).
"""

from __future__ import annotations

import math

import numpy as np

from planners.core.problem import PlanningError
from planners.core.timing import leg_time
from planners.teams.problem import TeamsProblem

Point = tuple[float, float]


class _Route:
    """One team's estimated route: start, then stops in order; ``time`` as described above."""

    def __init__(self, problem: TeamsProblem, team: int) -> None:
        p = problem.problems[team]
        self.motion = p.carrier.motion
        self.handling = problem.stop_time(team)
        self.points: list[Point] = [(p.start[0], p.start[1])]
        self.time = 0.0
        self.room = problem.capacity(team)

    def hop(self, a: Point, b: Point) -> float:
        return leg_time(math.dist(a, b), self.motion)

    def insertion(self, q: Point) -> tuple[float, int]:
        """Cheapest added time for a stop at ``q`` and the index to insert it at."""
        pts = self.points
        best, at = self.hop(pts[-1], q), len(pts)
        for j in range(1, len(pts)):
            delta = self.hop(pts[j - 1], q) + self.hop(q, pts[j]) - self.hop(pts[j - 1], pts[j])
            if delta < best:
                best, at = delta, j
        return best + self.handling, at


def construct(problem: TeamsProblem, groups: list[list[int]]) -> list[int]:
    """Team index of every pool item."""
    xy = np.array([q[:2] for q in problem.positions()], dtype=float).reshape(-1, 2)
    routes = [_Route(problem, k) for k in range(problem.n_teams)]
    starts = np.array([r.points[0] for r in routes], dtype=float)
    team_of = [-1] * problem.n_items
    queue = sorted(groups, key=lambda g: -float(np.min(np.linalg.norm(starts - xy[g].mean(axis=0), axis=1))))
    while queue:
        group = queue.pop(0)
        centre = (float(xy[group, 0].mean()), float(xy[group, 1].mean()))
        choice = _best_team(routes, centre, len(group))
        if choice is None:
            if len(group) == 1:
                raise PlanningError("the teams' decks hold fewer rovers than there are tasks")
            queue[:0] = [[i] for i in group]
            continue
        k, delta, at = choice
        routes[k].points.insert(at, centre)
        routes[k].time += delta
        routes[k].room -= len(group)
        for i in group:
            team_of[i] = k
    return team_of


def _best_team(routes: list[_Route], q: Point, size: int) -> tuple[int, float, int] | None:
    best: tuple[float, float, int, int] | None = None
    for k, r in enumerate(routes):
        if r.room < size:
            continue
        delta, at = r.insertion(q)
        worst = max([r.time + delta] + [o.time for j, o in enumerate(routes) if j != k])
        if best is None or (worst, delta) < best[:2]:
            best = (worst, delta, k, at)
    return None if best is None else (best[2], best[1], best[3])
