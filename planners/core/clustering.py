"""Cluster divider (dissertation Algorithm 3.1)."""

from __future__ import annotations

import math
from collections.abc import Sequence

_TIE = 1e-9


def divide_cluster(
    members: Sequence[int],
    points: Sequence[Sequence[float]],
    prev_point: Sequence[float],
) -> tuple[list[int], list[int]]:
    """Split a cluster in two around its (approximately) farthest pair of tasks.

    1) from an arbitrary task (the first) find the farthest task A, then the task B farthest
       from A; 2) every task joins the cluster of the nearer of A and B. If several tasks tie as
       farthest from A, the pair with the task nearest to the carrier wins (ch. 3.3's tie rule).
    Returns ``(near, far)``: the part whose seed is nearer to ``prev_point`` first (GET_ORDER).
    """
    if len(members) < 2:
        raise ValueError("a cluster of one task cannot be divided")
    dist = math.dist  # (timing.dist, without the call through it: the divider runs thousands of times)
    first = points[members[0]]
    a = max(members, key=lambda i: dist(points[i], first))  # first maximum = Algorithm 3.1's strict '>'
    pa = points[a]
    d_a = [dist(points[i], pa) for i in members]
    far = max(d_a)
    ties = [i for i, d in zip(members, d_a, strict=True) if d >= far - _TIE * max(1.0, far)]
    b = min(ties, key=lambda i: dist(points[i], prev_point)) if len(ties) > 1 else ties[0]
    if dist(points[a], prev_point) > dist(points[b], prev_point):
        a, b = b, a
    pa, pb = points[a], points[b]
    near: list[int] = []
    far_part: list[int] = []
    for i in members:
        p = points[i]
        (near if dist(p, pa) <= dist(p, pb) else far_part).append(i)
    if not far_part:  # all tasks coincide with A: split off one so the divider always divides
        far_part.append(near.pop())
    return near, far_part
