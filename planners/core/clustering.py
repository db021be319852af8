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
    seed, ties, d_seed = _seeds(members, points)
    a, b = _ordered(seed, ties, points, prev_point)
    return _parts(members, points, a, b, seed, d_seed)


class Divider:
    """``divide_cluster`` over fixed ``points``, remembering what does not depend on the carrier's
    position: per cluster (its members in order) task A and the tasks tied as farthest from it,
    per pair of seeds the two parts. The cluster searches divide the same clusters again in
    every round; only the tie rule and the order of the parts depend on ``prev_point``."""

    def __init__(self, points: Sequence[Sequence[float]]) -> None:
        self.points = points
        self._seeds: dict[tuple[int, ...], tuple[int, list[int], list[float]]] = {}
        self._parts: dict[tuple[tuple[int, ...], int, int], tuple[list[int], list[int]]] = {}

    def __call__(self, members: Sequence[int], prev_point: Sequence[float]) -> tuple[list[int], list[int]]:
        if len(members) < 2:
            raise ValueError("a cluster of one task cannot be divided")
        key = tuple(members)
        got = self._seeds.get(key)
        if got is None:
            got = self._seeds[key] = _seeds(members, self.points)
        seed, ties, d_seed = got
        a, b = _ordered(seed, ties, self.points, prev_point)
        parts = self._parts.get((key, a, b))
        if parts is None:
            parts = self._parts[(key, a, b)] = _parts(members, self.points, a, b, seed, d_seed)
        return list(parts[0]), list(parts[1])


def _seeds(members: Sequence[int], points: Sequence[Sequence[float]]) -> tuple[int, list[int], list[float]]:
    """Task A (farthest from the first member), the members tied as farthest from A, and every
    member's distance from A."""
    dist = math.dist  # (timing.dist, without the call through it: the divider runs thousands of times)
    first = points[members[0]]
    a = max(members, key=lambda i: dist(points[i], first))  # first maximum = Algorithm 3.1's strict '>'
    pa = points[a]
    d_a = [dist(points[i], pa) for i in members]
    far = max(d_a)
    near = far - _TIE * max(1.0, far)
    ties = [i for i, d in zip(members, d_a, strict=True) if d >= near]
    return a, ties, d_a


def _ordered(a: int, ties: list[int], points: Sequence[Sequence[float]],
             prev_point: Sequence[float]) -> tuple[int, int]:
    """The seeds (A, B) with B chosen among ``ties`` by the tie rule, the one nearer the carrier first."""
    dist = math.dist
    b = min(ties, key=lambda i: dist(points[i], prev_point)) if len(ties) > 1 else ties[0]
    if dist(points[a], prev_point) > dist(points[b], prev_point):
        a, b = b, a
    return a, b


def _parts(members: Sequence[int], points: Sequence[Sequence[float]], a: int, b: int, seed: int,
           d_seed: list[float]) -> tuple[list[int], list[int]]:
    """Every member to the nearer of seeds a and b (a on a tie); ``d_seed`` are the members'
    distances from task ``seed`` (one of a and b: not measured again)."""
    dist = math.dist
    pa, pb = points[a], points[b]
    near: list[int] = []
    far_part: list[int] = []
    for i, d in zip(members, d_seed, strict=True):
        p = points[i]
        da = d if a == seed else dist(p, pa)
        db = d if b == seed else dist(p, pb)
        (near if da <= db else far_part).append(i)
    if not far_part:  # all tasks coincide with A: split off one so the divider always divides
        far_part.append(near.pop())
    return near, far_part
