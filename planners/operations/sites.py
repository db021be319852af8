"""Sites: groups of tasks that rovers serve from one carrier position, in the carrier's order.

The tasks are ordered on a nearest-neighbour + 2-opt tour from the carrier's start
(``planners.core.routing``); the tour is cut into consecutive groups whose minimum enclosing
circle (``planners.core.geometry``) stays within ``radius`` and from whose centre every task's
launch flight stays within ``deploy_range``. The carrier serves the sites in tour order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planners.core.geometry import enclosing_circle
from planners.core.problem import Vec3
from planners.core.routing import two_opt_route
from planners.operations.problem import OperationProblem


@dataclass(frozen=True)
class Site:
    point: Vec3  # the carrier's position (ground)
    tasks: tuple[int, ...]  # indices into problem.tasks


def task_tour(problem: OperationProblem) -> list[int]:
    """The tasks in nearest-neighbour + 2-opt order from the carrier's start (ground positions)."""
    xy = np.array([t.position[:2] for t in problem.tasks], dtype=float).reshape(-1, 2)
    return two_opt_route(xy, np.array(problem.start[:2], dtype=float), long_tours=True)


def cut_sites(problem: OperationProblem, tour: list[int], radius: float) -> list[Site]:
    """Consecutive tasks of ``tour`` grouped while they fit a circle of ``radius`` whose centre
    launches every one of them within ``deploy_range``."""
    sites: list[Site] = []
    group: list[int] = []
    centre: Vec3 = problem.start
    for i in tour:
        trial = group + [i]
        c = _centre(problem, trial, radius)
        if c is None and group:
            sites.append(Site(centre, tuple(group)))
            trial, c = [i], _centre(problem, [i], radius)
        assert c is not None
        group, centre = trial, c
    if group:
        sites.append(Site(centre, tuple(group)))
    return sites


def _centre(problem: OperationProblem, members: list[int], radius: float) -> Vec3 | None:
    """The enclosing circle's centre of ``members`` when it serves them all, else None (a single
    task is always served from the ground point below it)."""
    pts = [problem.tasks[i].position for i in members]
    x, y, r = enclosing_circle([p[0] for p in pts], [p[1] for p in pts], [0.0] * len(pts))
    if len(members) == 1:
        return (pts[0][0], pts[0][1], 0.0)
    if r > radius:
        return None
    h = problem.takeoff_height
    if any(math.dist((x, y, h), p) > problem.deploy_range * (1 - 1e-9) for p in pts):
        return None
    return (x, y, 0.0)
