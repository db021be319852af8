"""Neighbourhood moves on an ordered list of clusters, shared by deployment and collection.

Each move is a small generator: given the clusters in visiting order (and ``fits``, whether one
stop can serve a cluster) it yields local changes ``(i, pieces, count)`` — replace clusters
i..i+count-1 by ``pieces`` — without scoring them. Scoring is the route's business: the cluster
searches of ``planners.deploy`` and ``planners.collection`` re-time a change with
``route.replace`` (quick) or re-place the whole route (fine), both on ``planners.timing``.
``local_search`` applies the moves until none makes the route faster; only improvements are kept.

Beyond the dissertation: Algorithms 4.2 and 5.2 only divide, swap two halves and merge back.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

Clusters = Sequence[Sequence[int]]
Change = tuple[int, list[list[int]], int]
Fits = Callable[[Sequence[int]], bool]
Move = Callable[[Clusters, Fits], Iterator[Change]]
R = TypeVar("R")

WINDOW = 4  # re-sequencing moves look this many stops ahead


def relocate(clusters: Clusters, fits: Fits) -> Iterator[Change]:
    """Hand one task (rover) over to the neighbouring cluster (the 3 + 1 splits a straight cut
    misses)."""
    for k in range(len(clusters) - 1):
        a, b = list(clusters[k]), list(clusters[k + 1])
        for r in a:
            if len(a) > 1 and fits([*b, r]):
                yield k, [[x for x in a if x != r], [*b, r]], 2
        for r in b:
            if len(b) > 1 and fits([*a, r]):
                yield k, [[*a, r], [x for x in b if x != r]], 2


def exchange(clusters: Clusters, fits: Fits) -> Iterator[Change]:
    """Exchange one task (rover) of a cluster with one of the next cluster."""
    for k in range(len(clusters) - 1):
        a, b = list(clusters[k]), list(clusters[k + 1])
        for r in a:
            for s in b:
                a2 = [s if x == r else x for x in a]
                b2 = [r if x == s else x for x in b]
                if fits(a2) and fits(b2):
                    yield k, [a2, b2], 2


def split_off(clusters: Clusters, fits: Fits) -> Iterator[Change]:
    """Serve one task (rover) from a stop of its own, just before or just after its cluster's."""
    for k, c in enumerate(clusters):
        if len(c) < 2:
            continue
        for r in c:
            rest = [x for x in c if x != r]
            yield k, [[r], rest], 1
            yield k, [rest, [r]], 1


def merge(clusters: Clusters, fits: Fits) -> Iterator[Change]:
    """Serve two consecutive clusters from one stop."""
    for k in range(len(clusters) - 1):
        union = [*clusters[k], *clusters[k + 1]]
        if fits(union):
            yield k, [union], 2


def swap(clusters: Clusters, fits: Fits) -> Iterator[Change]:
    """Visit two consecutive clusters the other way round (every route length, two stops included)."""
    for k in range(len(clusters) - 1):
        yield k, [list(clusters[k + 1]), list(clusters[k])], 2


def shift(clusters: Clusters, fits: Fits) -> Iterator[Change]:
    """Re-sequence: move one cluster up to ``WINDOW`` stops later or earlier (or-opt)."""
    n = len(clusters)
    for k in range(n):
        for j in range(k + 2, min(k + WINDOW, n - 1) + 1):  # k goes after j
            seg = [list(c) for c in clusters[k + 1:j + 1]]
            yield k, [*seg, list(clusters[k])], j - k + 1
        for j in range(max(k - WINDOW, 0), k - 1):  # k goes before j
            seg = [list(c) for c in clusters[j:k]]
            yield j, [list(clusters[k]), *seg], k - j + 1


def reverse(clusters: Clusters, fits: Fits) -> Iterator[Change]:
    """Re-sequence: visit up to ``WINDOW`` consecutive clusters backwards (2-opt)."""
    n = len(clusters)
    for k in range(n):
        for j in range(k + 2, min(k + WINDOW, n)):
            yield k, [list(c) for c in reversed(clusters[k:j + 1])], j - k + 1


MOVES: tuple[Move, ...] = (swap, relocate, split_off, merge, exchange, shift, reverse)


def apply(clusters: Clusters, change: Change) -> list[list[int]]:
    i, pieces, count = change
    return [list(c) for c in clusters[:i]] + pieces + [list(c) for c in clusters[i + count:]]


def local_search(route: R, fits: Fits, score: Callable[[R, Change], tuple[float, Any]],
                 accept: Callable[[R, Any], R], makespan: Callable[[R], float],
                 moves: Sequence[Move] = MOVES, rounds: int = 20,
                 stop: Callable[[], bool] | None = None) -> R:
    """First-improvement descent over ``moves``: ``score(route, change)`` → (makespan, candidate),
    ``accept(route, candidate)`` → the new route. Stops when no move helps, after ``rounds``
    improvements per move sweep, or when ``stop()`` says so (a time budget)."""
    for _ in range(rounds):
        improved = False
        for move in moves:
            restart = True
            while restart:
                restart = False
                clusters = route.clusters  # type: ignore[attr-defined]
                for change in move(clusters, fits):
                    t, cand = score(route, change)
                    if t < makespan(route) - 1e-9:
                        route, improved, restart = accept(route, cand), True, True
                        break
                    if stop is not None and stop():
                        return route
        if not improved:
            break
    return route
