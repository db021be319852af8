"""Pure planning maths for the marsupial team (dissertation ch. 3–6): no I/O, no MAVLink.

The registries name every planner; a planner's module (and the SciPy or shapely it needs) is
imported when the planner is first called, so that importing ``planners`` costs little more
than NumPy.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from planners.bounds import deploy_lower_bound
from planners.collection_bounds import collect_lower_bound
from planners.plan import Plan
from planners.problem import CollectProblem, DeployProblem, PlanningError


class LazyPlanner:
    """A registry entry: ``module.attr``, imported on the first call."""

    def __init__(self, module: str, attr: str) -> None:
        self.module, self.attr = module, attr
        self._fn: Callable[[Any], Plan] | None = None

    def load(self) -> Callable[[Any], Plan]:
        if self._fn is None:
            self._fn = getattr(importlib.import_module(self.module), self.attr)
        return self._fn

    def __call__(self, problem: Any) -> Plan:
        return self.load()(problem)

    def __repr__(self) -> str:
        return f"<planner {self.module}.{self.attr}>"


DEPLOY_PLANNERS: dict[str, Callable[[DeployProblem], Plan]] = {
    "lee": LazyPlanner("planners.deploy", "plan_lee"),
    "greedy2opt": LazyPlanner("planners.baselines", "plan_greedy2opt"),
    "direct": LazyPlanner("planners.baselines", "plan_direct"),
    "two-task": LazyPlanner("planners.two_task", "plan_two_tasks"),
    "lee-graph": LazyPlanner("planners.deploy_graph", "plan_lee_graph"),  # shapely, SciPy
}

COLLECT_PLANNERS: dict[str, Callable[[CollectProblem], Plan]] = {
    "lee": LazyPlanner("planners.collection", "plan_collect_lee"),
    "lee-convex": LazyPlanner("planners.collection_convex", "plan_collect_lee_convex"),  # SciPy
    "visit-all": LazyPlanner("planners.collection_baselines", "plan_collect_visit_all"),
    "gather": LazyPlanner("planners.collection_baselines", "plan_collect_gather"),
    "lee-graph": LazyPlanner("planners.collect_graph", "plan_collect_lee_graph"),  # shapely, SciPy
}

__all__ = ["COLLECT_PLANNERS", "DEPLOY_PLANNERS", "LazyPlanner", "Plan", "PlanningError",
           "collect_lower_bound", "deploy_lower_bound"]
