"""Pure planning maths for the marsupial team (dissertation ch. 3–6): no I/O, no MAVLink."""

from __future__ import annotations

from collections.abc import Callable

from planners.baselines import plan_direct, plan_greedy2opt
from planners.bounds import deploy_lower_bound
from planners.collect_graph import plan_collect_lee_graph
from planners.collection import plan_collect_lee
from planners.collection_baselines import plan_collect_gather, plan_collect_visit_all
from planners.collection_bounds import collect_lower_bound
from planners.collection_convex import plan_collect_lee_convex
from planners.deploy import plan_lee
from planners.deploy_graph import plan_lee_graph
from planners.plan import Plan
from planners.problem import CollectProblem, DeployProblem, PlanningError
from planners.two_task import plan_two_tasks

DEPLOY_PLANNERS: dict[str, Callable[[DeployProblem], Plan]] = {
    "lee": plan_lee,
    "greedy2opt": plan_greedy2opt,
    "direct": plan_direct,
    "two-task": plan_two_tasks,
    "lee-graph": plan_lee_graph,
}

COLLECT_PLANNERS: dict[str, Callable[[CollectProblem], Plan]] = {
    "lee": plan_collect_lee,
    "lee-convex": plan_collect_lee_convex,
    "visit-all": plan_collect_visit_all,
    "gather": plan_collect_gather,
    "lee-graph": plan_collect_lee_graph,
}

__all__ = ["COLLECT_PLANNERS", "DEPLOY_PLANNERS", "Plan", "PlanningError", "collect_lower_bound",
           "deploy_lower_bound"]
