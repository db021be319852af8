"""Pure planning maths for the marsupial team (dissertation ch. 3–6): no I/O, no MAVLink.

The registries name every planner; a planner's module (and the SciPy or shapely it needs) is
imported when the planner is first called, so that importing ``planners`` costs little more
than NumPy.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from planners.core.approach import WithApproach, WithTakeoff
from planners.core.collector import fewer_collections
from planners.core.lower_bound import deploy_lower_bound
from planners.core.plan import Plan
from planners.core.problem import CollectProblem, DeployProblem, PlanningError
from planners.core.ranges import WithRoverRanges


def collect_lower_bound(problem: CollectProblem) -> float:
    """A lower bound of any collection plan's makespan (``planners.collect.lower_bound``, imported on
    first use: it builds reach regions, which a deployment never needs)."""
    lower = importlib.import_module("planners.collect.lower_bound")
    return float(lower.collect_lower_bound(problem))


class LazyPlanner:
    """A registry entry: ``module.attr``, imported on the first call; each call runs with fewer
    garbage-collector passes (``planners.core.collector``)."""

    def __init__(self, module: str, attr: str) -> None:
        self.module, self.attr = module, attr
        self._fn: Callable[[Any], Plan] | None = None

    def load(self) -> Callable[[Any], Plan]:
        if self._fn is None:
            self._fn = getattr(importlib.import_module(self.module), self.attr)
        return self._fn

    def __call__(self, problem: Any) -> Plan:
        with fewer_collections():  # the garbage collector walks the planner's caches less often
            return self.load()(problem)

    def __repr__(self) -> str:
        return f"<planner {self.module}.{self.attr}>"


DEPLOY_PLANNERS: dict[str, Callable[[DeployProblem], Plan]] = {
    "lee": WithRoverRanges(WithTakeoff(LazyPlanner("planners.deploy.lee", "plan_lee"))),
    "greedy2opt": WithRoverRanges(WithTakeoff(LazyPlanner("planners.deploy.baselines", "plan_greedy2opt"))),
    "direct": WithRoverRanges(WithTakeoff(LazyPlanner("planners.deploy.baselines", "plan_direct"))),
    "two-task": WithRoverRanges(WithTakeoff(LazyPlanner("planners.deploy.two_task", "plan_two_tasks"))),
    # shapely, SciPy
    "lee-graph": WithRoverRanges(WithTakeoff(LazyPlanner("planners.roadmap.deploy", "plan_lee_graph"))),
}

COLLECT_PLANNERS: dict[str, Callable[[CollectProblem], Plan]] = {
    "lee": WithApproach(LazyPlanner("planners.collect.lee", "plan_collect_lee")),
    "lee-convex": WithApproach(LazyPlanner("planners.collect.convex", "plan_collect_lee_convex")),  # SciPy
    "visit-all": WithApproach(LazyPlanner("planners.collect.baselines", "plan_collect_visit_all")),
    "gather": WithApproach(LazyPlanner("planners.collect.baselines", "plan_collect_gather")),
    # shapely, SciPy
    "lee-graph": WithApproach(LazyPlanner("planners.roadmap.collect", "plan_collect_lee_graph")),
}

# Cheaper forms for screening many candidate problems (the teams allocation's shares): a planner
# not listed screens with itself.
SCREEN_PLANNERS: dict[str, dict[str, Callable[[Any], Plan]]] = {
    "deploy": {"lee": WithTakeoff(LazyPlanner("planners.deploy.lee", "plan_lee_screen")),
               "lee-graph": WithTakeoff(LazyPlanner("planners.roadmap.deploy", "plan_lee_graph_screen"))},
    "collect": {"lee": WithApproach(LazyPlanner("planners.collect.lee", "plan_collect_lee_screen")),
                "lee-graph": WithApproach(LazyPlanner("planners.roadmap.collect",
                                                      "plan_collect_lee_graph_screen"))},
}

__all__ = ["COLLECT_PLANNERS", "DEPLOY_PLANNERS", "SCREEN_PLANNERS", "LazyPlanner", "Plan", "PlanningError",
           "collect_lower_bound", "deploy_lower_bound"]
