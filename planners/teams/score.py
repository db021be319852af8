"""Each team's plan for a share of the pool, by the team planner, cached by (team, share).

Every time quoted comes from the team planner's plan, which ``planners.core.timing`` times: the
allocation search never estimates what it scores.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Generic

from planners.core.plan import Plan
from planners.core.problem import PlanningError
from planners.teams.problem import P, TeamsProblem

Share = frozenset[int]


class TeamScorer(Generic[P]):
    """``makespan(team, share)``: the team planner's makespan for that share (inf = infeasible)."""

    def __init__(self, problem: TeamsProblem[P], planner: Callable[[P], Plan]) -> None:
        self.problem: TeamsProblem[P] = problem
        self.planner: Callable[[P], Plan] = planner
        self.calls = 0  # planner calls so far (cache misses)
        self._plans: dict[tuple[int, Share], Plan | None] = {}

    def plan(self, team: int, share: Iterable[int]) -> Plan | None:
        """The team's plan for ``share``; None when the planner cannot serve it (or too many tasks)."""
        key = (team, frozenset(share))
        if key not in self._plans:
            self._plans[key] = self._solve(team, sorted(key[1]))
        return self._plans[key]

    def makespan(self, team: int, share: Iterable[int]) -> float:
        plan = self.plan(team, share)
        return math.inf if plan is None else plan.makespan

    def _solve(self, team: int, members: list[int]) -> Plan | None:
        p = self.problem.problems[team]
        if not members:
            kind = self.problem.kind
            return Plan(kind=kind, planner="none", start=p.start, heading=p.heading, stops=[])
        if len(members) > self.problem.capacity(team):
            return None
        self.calls += 1
        try:
            return self.planner(self.problem.restrict(team, members))
        except PlanningError:
            return None
