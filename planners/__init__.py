"""Pure planning maths for the marsupial team (dissertation ch. 3–6): no I/O, no MAVLink."""

from __future__ import annotations

from collections.abc import Callable

from planners.baselines import plan_direct, plan_greedy2opt
from planners.bounds import deploy_lower_bound
from planners.deploy import plan_lee
from planners.plan import Plan
from planners.problem import DeployProblem, PlanningError
from planners.two_task import plan_two_tasks

DEPLOY_PLANNERS: dict[str, Callable[[DeployProblem], Plan]] = {
    "lee": plan_lee,
    "greedy2opt": plan_greedy2opt,
    "direct": plan_direct,
    "two-task": plan_two_tasks,
}

__all__ = ["DEPLOY_PLANNERS", "Plan", "PlanningError", "deploy_lower_bound"]
