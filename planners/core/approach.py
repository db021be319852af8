"""Rover flights that start (deployment) or end (collection) above the deck, not on it.

A launched rover climbs to ``takeoff_height`` above its stop and flies its line to the task from
there; the planners solve the deployment with each task's height ``z`` lifted to ``|z − h|``
(the same flight from the ground) and the paths are put back (:class:`WithTakeoff`).

A returning rover flies to the point ``approach_height`` above its stop and comes down onto the
deck from there (the time model's ``land_time``). Its flight is the line (or roadmap polyline)
from where it is to that point. Every collection planner measures a rover's flight from its
height ``z`` to the stop on the ground; a rover at ``|z − h|`` has exactly the same flight to the
ground as a rover at ``z`` to the height ``h``, so the planners solve the problem with the heights
*lifted* that way, and the paths are put back afterwards (:func:`with_approach`), each vertex's
height moved evenly along the path's ground length, which keeps every length and so every time.
``approach_height = 0`` is the dissertation's model.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

from planners.core.plan import Plan
from planners.core.problem import CollectProblem, DeployProblem, Task, Vec3


def lifted(problem: CollectProblem) -> CollectProblem:
    """The same collection with each rover's height ``z`` replaced by ``|z − approach_height|``."""
    h = problem.approach_height
    rovers = tuple(dataclasses.replace(r, position=(r.position[0], r.position[1], abs(r.position[2] - h)))
                   for r in problem.rovers)
    return dataclasses.replace(problem, rovers=rovers, approach_height=0.0)


def lifted_tasks(problem: DeployProblem) -> DeployProblem:
    """The same deployment with each task's height ``z`` replaced by ``|z − takeoff_height|``."""
    h = problem.takeoff_height
    tasks = tuple(Task(t.id, (t.position[0], t.position[1], abs(t.position[2] - h))) for t in problem.tasks)
    return dataclasses.replace(problem, tasks=tasks, takeoff_height=0.0)


def restored_tasks(plan: Plan, problem: DeployProblem) -> Plan:
    """``plan`` (made for :func:`lifted_tasks`) with each rover's path from the take-off height
    above its stop to its task."""
    h = problem.takeoff_height
    height = {t.id: float(t.position[2]) for t in problem.tasks}
    for leg in plan.legs():
        if leg.task in height:
            leg.path = _put_back(list(leg.path), h, height[leg.task])
    if plan.time_model is not None:
        plan.time_model = {**plan.time_model, "takeoff_height": h}
    return plan


def _put_back(path: list[Vec3], z0: float, h: float) -> list[Vec3]:
    ground = [0.0]
    for p, q in zip(path, path[1:], strict=False):
        ground.append(ground[-1] + math.hypot(q[0] - p[0], q[1] - p[1]))
    total = ground[-1]
    n = len(path) - 1
    out = []
    for i, p in enumerate(path):
        f = ground[i] / total if total > 1e-12 else (i / n if n else 1.0)
        out.append((p[0], p[1], z0 + (h - z0) * f))
    return out


def restored(plan: Plan, problem: CollectProblem) -> Plan:
    """``plan`` (made for :func:`lifted`) with each rover's path from its real position to the
    approach point above its stop."""
    h = problem.approach_height
    start = {r.id: r.position for r in problem.rovers}
    for leg in plan.legs():
        z0 = float(start[leg.rover][2]) if leg.rover in start else float(leg.path[0][2])
        leg.path = _put_back(list(leg.path), z0, h)
    if plan.time_model is not None:
        plan.time_model = {**plan.time_model, "approach_height": h}
    return plan


class WithApproach:
    """A collection planner that honours ``approach_height`` (see the module docstring)."""

    def __init__(self, inner: Callable[[CollectProblem], Plan]) -> None:
        self.inner = inner

    def load(self) -> Any:
        load = getattr(self.inner, "load", None)
        return load() if load is not None else self.inner

    def __call__(self, problem: CollectProblem) -> Plan:
        if problem.approach_height <= 0.0:
            return self.inner(problem)
        return restored(self.inner(lifted(problem)), problem)

    def __repr__(self) -> str:
        return f"<with approach {self.inner!r}>"


class WithTakeoff:
    """A deployment planner that honours ``takeoff_height`` (see the module docstring)."""

    def __init__(self, inner: Callable[[DeployProblem], Plan]) -> None:
        self.inner = inner

    def load(self) -> Any:
        load = getattr(self.inner, "load", None)
        return load() if load is not None else self.inner

    def __call__(self, problem: DeployProblem) -> Plan:
        if problem.takeoff_height <= 0.0:
            return self.inner(problem)
        return restored_tasks(self.inner(lifted_tasks(problem)), problem)

    def __repr__(self) -> str:
        return f"<with take-off {self.inner!r}>"


__all__ = ["WithApproach", "WithTakeoff", "lifted", "lifted_tasks", "restored", "restored_tasks"]
