"""The baseline: every task (or rover to collect) goes to the team whose carrier starts nearest.

Items nearest to some start choose first; an item whose nearest team's deck is full goes to the
next nearest team with room. Each team then plans its share with the team planner.
"""

from __future__ import annotations

import numpy as np

from planners.core.problem import PlanningError
from planners.teams.problem import TeamsProblem


def nearest_assignment(problem: TeamsProblem) -> list[int]:
    """Team index of every pool item, by the distance from each carrier's start."""
    xy = np.array([q[:2] for q in problem.positions()], dtype=float).reshape(-1, 2)
    starts = np.array([s[:2] for s in problem.starts()], dtype=float).reshape(-1, 2)
    dist = np.linalg.norm(xy[:, None] - starts[None], axis=2)
    room = [problem.capacity(k) for k in range(problem.n_teams)]
    team_of = [-1] * problem.n_items
    for i in np.argsort(dist.min(axis=1), kind="stable"):
        free = [int(k) for k in np.argsort(dist[i], kind="stable") if room[int(k)] > 0]
        if not free:
            raise PlanningError(f"{problem.n_items} tasks need as many rovers, only "
                                f"{sum(problem.capacity(k) for k in range(problem.n_teams))} on the carriers")
        team_of[int(i)] = free[0]
        room[free[0]] -= 1
    return team_of
