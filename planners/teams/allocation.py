"""Share a mission's tasks (deployment) or rovers (collection) between several teams so that the
latest team finishes as early as possible, and plan every team with today's planners.

1. the fast construction (``construction``: the teams' estimated times to the item groups) and
   the nearest-carrier baseline (``baseline``) are both scored exactly; the better one starts
2. the search (``search``): groups and single items move between teams while the makespan (then
   the next latest team's, and so on) improves, every candidate planned by the team planner.

So the result is never worse than the nearest-carrier baseline.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from planners.core.plan import Plan
from planners.core.problem import PlanningError
from planners.teams.baseline import nearest_assignment
from planners.teams.clusters import item_clusters
from planners.teams.construction import construct
from planners.teams.plan import TeamPlan, TeamsPlan
from planners.teams.problem import P, TeamsProblem
from planners.teams.score import TeamScorer
from planners.teams.search import Allocation, better, improve

MAX_CALLS = 300  # planner calls the search may spend (each team plan of a share is one call)


def plan_teams(problem: TeamsProblem[P], planner: Callable[[P], Plan], name: str,
               max_calls: int = MAX_CALLS, screen: Callable[[P], Plan] | None = None) -> TeamsPlan:
    """The allocation of the module docstring; ``name`` is the team planner's. With ``screen`` (a
    cheaper form of ``planner``, ``planners.SCREEN_PLANNERS``) the construction and the search
    score their candidate shares with it, and ``planner`` plans the shares found and the
    nearest-carrier baseline's: the better of the two is kept, so never worse than the baseline."""
    t0 = time.perf_counter()
    _check_decks(problem)
    final = TeamScorer(problem, planner)
    scorer = final if screen is None else TeamScorer(problem, screen)
    groups = item_clusters(problem)
    near = nearest_assignment(problem)
    nearest = Allocation(scorer, near)
    built = Allocation(scorer, construct(problem, groups))
    alloc = built if better(built.key(), nearest.key()) else nearest
    alloc = improve(alloc, groups, max_calls)  # in place (``nearest`` too when the search began there)
    nearest = Allocation(final, near)  # the baseline, planned by the planner itself
    if screen is not None:  # the shares found, planned by the planner itself; the better of the two
        alloc = Allocation(final, alloc.team_of)
        alloc = nearest if better(nearest.key(), alloc.key()) else alloc
    out = teams_plan(final, alloc, name, "search", t0)
    out.baseline_makespan = nearest.makespan()
    out.notes.append(f"{scorer.calls} team plans computed" + (
        f" (screened by {name}'s quick form, then {final.calls} by {name})" if screen is not None else ""))
    return out


def plan_teams_nearest(problem: TeamsProblem[P], planner: Callable[[P], Plan], name: str) -> TeamsPlan:
    """The baseline: every item to the nearest carrier (``baseline``), each team planned by ``planner``."""
    t0 = time.perf_counter()
    _check_decks(problem)
    scorer = TeamScorer(problem, planner)
    return teams_plan(scorer, Allocation(scorer, nearest_assignment(problem)), name, "nearest", t0)


def teams_plan(scorer: TeamScorer, alloc: Allocation, name: str, how: str, t0: float) -> TeamsPlan:
    problem = scorer.problem
    teams = []
    for k, carrier in enumerate(problem.carriers):
        plan = scorer.plan(k, alloc.shares[k])
        if plan is None:
            raise PlanningError(f"no team can serve every {'task' if problem.kind == 'deploy' else 'rover'}: "
                                f"planner {name!r} cannot plan carrier {carrier}'s share")
        teams.append(TeamPlan(carrier, plan))
    return TeamsPlan(problem.kind, name, how, teams, compute_ms=(time.perf_counter() - t0) * 1e3)


def _check_decks(problem: TeamsProblem) -> None:
    room = sum(problem.capacity(k) for k in range(problem.n_teams))
    if room < problem.n_items:
        raise PlanningError(f"{problem.n_items} tasks need as many rovers, "
                            f"only {room} on the carriers' decks")
