"""The operation planner (``plan_operation``): the dispatch construction under a few policies
(site radius, work per sortie, battery margin), the earliest operation end kept."""

from __future__ import annotations

import math
import time

from planners.core.problem import PlanningError
from planners.operations.dispatch import Policy, dispatch
from planners.operations.plan import OperationPlan
from planners.operations.problem import OperationProblem
from planners.operations.sites import cut_sites, task_tour

RADII = (1.0, 0.6, 0.3)  # site radius as a fraction of the deploy range
CAPS = (math.inf, 0.5, 0.3)  # work per sortie as a fraction of the battery's air time (inf: no cap)


def policies(problem: OperationProblem) -> list[Policy]:
    c = problem.carrier
    margin = 2.0 * (c.deploy_stop_time + c.collect_stop_time)
    return [Policy(problem.deploy_range * r, problem.air_budget * cap if math.isfinite(cap) else math.inf,
                   margin) for r in RADII for cap in CAPS]


def plan_operation(problem: OperationProblem) -> OperationPlan:
    """Schedule the whole operation: the best plan over :func:`policies` (PlanningError when none
    keeps every battery)."""
    t0 = time.perf_counter()
    if not problem.rovers:
        raise PlanningError("an operation needs at least one rover")
    tour = task_tour(problem)
    best: OperationPlan | None = None
    why = "no policy"
    for policy in policies(problem):
        try:
            plan = dispatch(problem, cut_sites(problem, tour, policy.radius), policy, "operation")
        except PlanningError as e:
            why = str(e)
            continue
        if best is None or plan.makespan < best.makespan:
            best = plan
    if best is None:
        raise PlanningError(f"no schedule keeps every rover's battery: {why}")
    best.compute_ms = (time.perf_counter() - t0) * 1e3
    return best
