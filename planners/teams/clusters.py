"""Groups of pool items that one stop can serve: the units the allocation moves between teams.

A leader is the unassigned item with the most unassigned neighbours; its group is the leader and
every unassigned item that reaches the leader's ground point (horizontal distance within the
item's reach). So a group can always be served from one stop, at its leader's ground point.
"""

from __future__ import annotations

import numpy as np

from planners.core.problem import DeployProblem
from planners.teams.problem import TeamsProblem


def ground_reach(problem: TeamsProblem) -> np.ndarray:
    """Each pool item's horizontal reach: sqrt(range² − z²) with d_deploy (deployment) or the
    rover's remaining range (collection)."""
    p = problem.problems[0]
    z = np.array([q[2] for q in problem.positions()], dtype=float).reshape(-1)
    if isinstance(p, DeployProblem):
        rng = np.full(len(z), p.deploy_range)
    else:
        rng = np.array([r.range for r in p.rovers], dtype=float).reshape(-1)
    return np.sqrt(np.maximum(rng * rng - z * z, 0.0))


def item_clusters(problem: TeamsProblem) -> list[list[int]]:
    """Pool items in groups (see the module docstring), largest first."""
    xy = np.array([q[:2] for q in problem.positions()], dtype=float).reshape(-1, 2)
    reach = ground_reach(problem)
    joins = np.linalg.norm(xy[:, None] - xy[None], axis=2) <= reach[:, None]  # [i, L]: i reaches L
    free = np.ones(len(xy), dtype=bool)
    groups: list[list[int]] = []
    while free.any():
        counts = np.where(free, (joins & free[:, None]).sum(axis=0), -1)
        leader = int(np.argmax(counts))
        members = np.flatnonzero(joins[:, leader] & free)
        groups.append([int(i) for i in members])
        free[members] = False
    return groups
