"""Rovers with less than the deploy range (:attr:`DeployProblem.rover_ranges`).

The planners of chapters 4 and 6 give every rover the same range ``d_deploy``. A rover whose battery
flies less is planned with the range it has, around any planner:

1. a rover whose range reaches no task (less than the lowest task's height above the take-off
   height, ``|z − takeoff_height|``: the flight with the carrier right under it) is not planned;
2. the planner plans with the others and ``deploy_range``; when every flight of the plan is within
   the range of a rover that can fly it - the longest flight to the rover with the most range, and
   so on down (any rover on the deck may fly any task of a stop) - the rovers are swapped onto
   those flights and the plan is kept;
3. otherwise the deployment is planned again with the shortest range among the rovers that will
   fly (the ``len(tasks)`` with the most range), and those rovers are put on its flights the same
   way; a task out of that range is a :class:`PlanningError`.

Swapping rovers between flights changes no time: every rover has the same motion.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

from planners.core.plan import Plan, RoverLeg
from planners.core.problem import DeployProblem, PlanningError
from planners.core.timing import RANGE_MARGIN

TOLERANCE = 1e-4  # m: a flight this much over a rover's range is still within it (rounding)


def leg_length(leg: RoverLeg) -> float:
    """The length of a rover's flight (its path's 3-D polyline)."""
    return sum(math.dist(p, q) for p, q in zip(leg.path, leg.path[1:], strict=False))


def min_reach(problem: DeployProblem) -> float:
    """The shortest flight any task needs: the lowest ``|z − takeoff_height|``."""
    return min((abs(t.position[2] - problem.takeoff_height) for t in problem.tasks), default=0.0)


def fit_rovers(plan: Plan, problem: DeployProblem, rovers: list[str]) -> bool:
    """Put ``rovers`` (ids of ``problem``) on the plan's flights so that each flies within its
    range (see the module docstring); False, and the plan unchanged, when they cannot."""
    legs = [leg for leg in plan.legs() if leg.task is not None]

    def fits(leg: RoverLeg, rid: str) -> bool:
        return leg_length(leg) <= problem.rover_range(rid) + TOLERANCE

    if all(leg.rover in rovers and fits(leg, leg.rover) for leg in legs):
        return True
    longest = sorted(legs, key=leg_length, reverse=True)
    most = sorted(rovers, key=problem.rover_range, reverse=True)[: len(legs)]
    if len(most) < len(legs) or not all(fits(leg, rid) for leg, rid in zip(longest, most, strict=True)):
        return False
    for leg, rid in zip(longest, most, strict=True):
        leg.rover = rid
    return True


class WithRoverRanges:
    """A deployment planner that honours ``rover_ranges`` (see the module docstring)."""

    def __init__(self, inner: Callable[[DeployProblem], Plan]) -> None:
        self.inner = inner

    def load(self) -> Any:
        load = getattr(self.inner, "load", None)
        return load() if load is not None else self.inner

    def __call__(self, problem: DeployProblem) -> Plan:
        ids = problem.rover_ids()
        if all(problem.rover_range(rid) >= problem.deploy_range for rid in ids):
            return self.inner(problem)
        reach = min_reach(problem)
        able = [rid for rid in ids if problem.rover_range(rid) + RANGE_MARGIN >= reach]
        n = len(problem.tasks)
        if len(able) < n:
            short = ", ".join(f"{rid} {problem.rover_range(rid):.1f} m" for rid in ids if rid not in able)
            raise PlanningError(f"{len(able)} rover(s) can reach a task for {n} tasks: the battery ranges of "
                                f"{short} reach no task (the nearest needs {reach:.1f} m)")
        plan = self.inner(dataclasses.replace(problem, rovers=tuple(able)))
        if fit_rovers(plan, problem, able):
            return plan
        flying = sorted(able, key=problem.rover_range, reverse=True)[:n]
        shortest = min(problem.rover_range(rid) for rid in flying)
        again = dataclasses.replace(problem, deploy_range=shortest, rover_ranges=(),
                                    rovers=tuple(rid for rid in able if rid in flying))
        try:
            plan = self.inner(again)
        except PlanningError as exc:
            raise PlanningError(f"with the rovers' battery ranges (the {n} with the most fly, the shortest "
                                f"{shortest:.1f} m): {exc}") from None
        if not fit_rovers(plan, problem, flying):  # every flight is within `shortest`
            raise PlanningError(f"the plan's flights do not fit the rovers' battery ranges "
                                f"(shortest {shortest:.1f} m)")
        plan.notes.append(f"planned with a deploy range of {shortest:.1f} m: the battery range of a rover "
                          "that flies")
        return plan

    def __repr__(self) -> str:
        return f"<with rover ranges {self.inner!r}>"


__all__ = ["WithRoverRanges", "fit_rovers", "leg_length", "min_reach"]
