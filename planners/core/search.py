"""The cluster search shared by deployment and collection.

Algorithm 4.2 (deployment) and 5.2 (collection) are the same loop: divide a cluster with
Algorithm 3.1, try the two halves in both orders, keep the faster route or merge them back. The
moves after it (re-sequencing, swapping and merging neighbours) go beyond the dissertation; each
keeps a change only when the route gets faster. A route here is any object with ``clusters``,
``positions``, ``makespan``, ``replace(i, pieces, count)`` → candidate whose first element is its
makespan, and ``accept(candidate)`` → the new route.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol, TypeVar

import numpy as np

from planners.core.routing import two_opt_route

Point2 = tuple[float, float]
R = TypeVar("R", bound="ClusterRoute")


class ClusterRoute(Protocol):
    clusters: list[list[int]]
    positions: list[Point2]
    makespan: float

    def replace(self, i: int, pieces: list[list[int]], count: int = 1) -> tuple[Any, ...]: ...

    def accept(self: R, candidate: tuple[Any, ...]) -> R: ...


SCREEN_AHEAD = 256  # clusters whose divisions are screened at once (again after every division kept)
SCREEN_FROM = 40  # clusters: shorter routes score every division exactly (numpy's calls cost more)


def split_loop(route: R, divide: Callable[[R, int], tuple[list[int], list[int]]],
               tried: set[tuple] | None = None, accept_ties: bool = True) -> R:
    """DIVIDE_CLUSTER / SWAP_CLUSTERS / MERGE_CLUSTERS of Algorithms 4.2 and 5.2.

    ``tried`` remembers divisions merged back (with the neighbouring clusters) so that later rounds
    of the improvement search do not evaluate them again. ``accept_ties`` keeps a division that is
    exactly as fast (Algorithm 4.2's T_cand ≤ T_min). A route with ``screen`` (lower bounds of
    many changes at once) has its divisions screened first: one whose bound shows it cannot be
    kept is merged back without being scored (the same result, fewer exact scores).
    """
    tried = set() if tried is None else tried
    screened: dict[int, tuple[float, tuple[list[int], list[int]]]] = {}  # for the current route
    idx = 0
    while idx < len(route.clusters):
        members = route.clusters[idx]
        if len(members) == 1:  # a cluster of one cannot be divided
            idx += 1
            continue
        key = _key(route, idx)
        if key in tried:
            idx += 1
            continue
        if idx not in screened:
            screened = _screen_divisions(route, divide, tried, idx)
        bound, (near, far) = screened[idx]
        if bound > route.makespan or (not accept_ties and bound >= route.makespan - 1e-9):
            tried.add(key)
            idx += 1
            continue
        cand = route.replace(idx, [near, far])
        swapped = route.replace(idx, [far, near])
        if swapped[0] < cand[0]:
            cand = swapped
        if cand[0] < route.makespan - 1e-9 or (accept_ties and cand[0] <= route.makespan):
            route = route.accept(cand)
            screened = {}
        else:
            tried.add(key)
            idx += 1
    return route


def _key(route: ClusterRoute, idx: int) -> tuple:
    return (tuple(route.clusters[idx - 1]) if idx else (), tuple(route.clusters[idx]),
            tuple(route.clusters[idx + 1]) if idx + 1 < len(route.clusters) else ())


def _screen_divisions(route: R, divide: Callable[[R, int], tuple[list[int], list[int]]], tried: set[tuple],
                      start: int) -> dict[int, tuple[float, tuple[list[int], list[int]]]]:
    """The division of the clusters from ``start`` on (``SCREEN_AHEAD`` of them) that
    ``split_loop`` would try, and a lower bound of its better order's makespan (the route's
    ``screen``; without one or on a route shorter than ``SCREEN_FROM``, only the cluster at
    ``start``, bound −inf)."""
    screen = getattr(route, "screen", None) if len(route.clusters) >= SCREEN_FROM else None
    if screen is None:
        return {start: (-np.inf, divide(route, start))}
    todo = [j for j in range(start, min(start + SCREEN_AHEAD, len(route.clusters)))
            if len(route.clusters[j]) > 1 and (j == start or _key(route, j) not in tried)]
    parts = {j: divide(route, j) for j in todo}
    changes = [(j, [a, b] if order == 0 else [b, a], 1) for j, (a, b) in parts.items() for order in (0, 1)]
    bounds = screen(changes)
    return {j: (float(min(bounds[2 * t], bounds[2 * t + 1])), d) for t, (j, d) in enumerate(parts.items())}


def merge_neighbours(route: R, fits: Callable[[Sequence[int]], bool]) -> R:
    """Merge consecutive clusters that one stop can serve when that is faster (one stop less)."""
    k = 0
    while k + 1 < len(route.clusters):
        union = route.clusters[k] + route.clusters[k + 1]
        if fits(union):
            cand = route.replace(k, [union], count=2)
            if cand[0] < route.makespan - 1e-9:
                route = route.accept(cand)
                continue
        k += 1
    return route


def swap_neighbours(route: R) -> R:
    """Visit consecutive clusters the other way round when that is faster (SWAP_CLUSTERS applied
    to every neighbouring pair, including the initial division's)."""
    k = 0
    while k + 1 < len(route.clusters):
        cand = route.replace(k, [route.clusters[k + 1], route.clusters[k]], count=2)
        if cand[0] < route.makespan - 1e-9:
            route = route.accept(cand)
        k += 1
    return route


def reorder(route: R, anchors: Sequence[Point2], start: Point2, rebuild: Callable[[list[list[int]]], R]) -> R:
    """Re-sequence the clusters as an open tour over ``anchors`` (2-opt from the current order, and
    nearest neighbour + 2-opt) and keep the faster route: the division order can make the
    carrier's path cross itself."""
    if len(route.clusters) < 3:
        return route
    pts = np.array(anchors, dtype=float)
    best = route
    for initial in (list(range(len(pts))), None):
        order = two_opt_route(pts, np.array(start, dtype=float), initial, long_tours=True)
        if order == list(range(len(pts))):
            continue
        cand = rebuild([route.clusters[i] for i in order])
        if cand.makespan < best.makespan:
            best = cand
    return best
