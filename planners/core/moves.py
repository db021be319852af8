"""Neighbourhood moves on an ordered list of clusters, shared by deployment and collection.

Each move is a small generator: given the clusters in visiting order (and ``fits``, whether one
stop can serve a cluster) it yields local changes ``(i, pieces, count)`` — replace clusters
i..i+count-1 by ``pieces`` — without scoring them. Scoring is the route's business: the search
driver (``planners.core.driver``, for ``planners.deploy.lee`` and ``planners.collect.lee``) re-times a
change with ``route.replace`` (quick) or re-places the whole route (fine), both on
``planners.core.timing``.
``local_search`` applies the moves until none makes the route faster; only improvements are kept.

Beyond the dissertation: Algorithms 4.2 and 5.2 only divide, swap two halves and merge back.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

Clusters = Sequence[Sequence[int]]
Change = tuple[int, list[list[int]], int]
Fits = Callable[[Sequence[int]], bool]
Move = Callable[[Clusters, Fits, int], Iterator[Change]]
R = TypeVar("R")

WINDOW = 4  # re-sequencing moves look this many stops ahead


def relocate(clusters: Clusters, fits: Fits, start: int = 0) -> Iterator[Change]:
    """Hand one task (rover) over to the neighbouring cluster (the 3 + 1 splits a straight cut
    misses)."""
    for k in range(start, len(clusters) - 1):
        a, b = list(clusters[k]), list(clusters[k + 1])
        for r in a:
            if len(a) > 1 and fits([*b, r]):
                yield k, [[x for x in a if x != r], [*b, r]], 2
        for r in b:
            if len(b) > 1 and fits([*a, r]):
                yield k, [[*a, r], [x for x in b if x != r]], 2


def relocate_nearest(near: Callable[[Sequence[int]], Callable[[int], float]], keep: int = 2) -> Move:
    """``relocate`` with a bounded candidate list: of each cluster only the ``keep`` members
    nearest the neighbouring cluster are handed over (long routes). ``near(cluster)`` gives the
    key that ranks items by their nearness to ``cluster`` (made once per neighbour, not per item)."""
    def move(clusters: Clusters, fits: Fits, start: int = 0) -> Iterator[Change]:
        if keep <= 0:  # nothing to hand over (and no members to sort by nearness)
            return
        for k in range(start, len(clusters) - 1):
            a, b = list(clusters[k]), list(clusters[k + 1])
            # (sorted(…)[:keep] is heapq.nsmallest's documented equivalent, ties in order: faster on
            # a cluster's few members)
            if len(a) > 1:
                for r in sorted(a, key=near(b))[:keep]:
                    if fits([*b, r]):
                        yield k, [[x for x in a if x != r], [*b, r]], 2
            if len(b) > 1:
                for r in sorted(b, key=near(a))[:keep]:
                    if fits([*a, r]):
                        yield k, [[*a, r], [x for x in b if x != r]], 2
    move.__name__ = "relocate_nearest"
    return move


def exchange(clusters: Clusters, fits: Fits, start: int = 0) -> Iterator[Change]:
    """Exchange one task (rover) of a cluster with one of the next cluster."""
    for k in range(start, len(clusters) - 1):
        a, b = list(clusters[k]), list(clusters[k + 1])
        for r in a:
            for s in b:
                a2 = [s if x == r else x for x in a]
                b2 = [r if x == s else x for x in b]
                if fits(a2) and fits(b2):
                    yield k, [a2, b2], 2


def split_off(clusters: Clusters, fits: Fits, start: int = 0) -> Iterator[Change]:
    """Serve one task (rover) from a stop of its own, just before or just after its cluster's."""
    for k in range(start, len(clusters)):
        c = clusters[k]
        if len(c) < 2:
            continue
        for r in c:
            rest = [x for x in c if x != r]
            yield k, [[r], rest], 1
            yield k, [rest, [r]], 1


def split(clusters: Clusters, fits: Fits, start: int = 0) -> Iterator[Change]:
    """Serve one cluster from two stops, divided every way into parts of two or more (clusters of
    up to ``SPLIT_UPTO`` members; ``split_off`` gives the parts of one), in both orders: a straight
    cut (Algorithm 3.1) misses divisions such as two far rovers and two near ones."""
    for k in range(start, len(clusters)):
        c = list(clusters[k])
        if not 4 <= len(c) <= SPLIT_UPTO:
            continue
        for mask in range(1, 1 << (len(c) - 1)):  # the last member stays in the second part
            a = [x for j, x in enumerate(c) if mask >> j & 1]
            b = [x for j, x in enumerate(c) if not mask >> j & 1]
            if len(a) >= 2 and len(b) >= 2:
                yield k, [a, b], 1
                yield k, [b, a], 1


def merge(clusters: Clusters, fits: Fits, start: int = 0) -> Iterator[Change]:
    """Serve two consecutive clusters from one stop."""
    for k in range(start, len(clusters) - 1):
        union = [*clusters[k], *clusters[k + 1]]
        if fits(union):
            yield k, [union], 2


def swap(clusters: Clusters, fits: Fits, start: int = 0) -> Iterator[Change]:
    """Visit two consecutive clusters the other way round (every route length, two stops included)."""
    for k in range(start, len(clusters) - 1):
        yield k, [list(clusters[k + 1]), list(clusters[k])], 2


def shift(clusters: Clusters, fits: Fits, start: int = 0) -> Iterator[Change]:
    """Re-sequence: move one cluster up to ``WINDOW`` stops later or earlier (or-opt)."""
    n = len(clusters)
    for k in range(start, n):
        for j in range(k + 2, min(k + WINDOW, n - 1) + 1):  # k goes after j
            seg = [list(c) for c in clusters[k + 1:j + 1]]
            yield k, [*seg, list(clusters[k])], j - k + 1
        for j in range(max(k - WINDOW, 0), k - 1):  # k goes before j
            seg = [list(c) for c in clusters[j:k]]
            yield j, [list(clusters[k]), *seg], k - j + 1


def reverse(clusters: Clusters, fits: Fits, start: int = 0) -> Iterator[Change]:
    """Re-sequence: visit up to ``WINDOW`` consecutive clusters backwards (2-opt)."""
    n = len(clusters)
    for k in range(start, n):
        for j in range(k + 2, min(k + WINDOW, n)):
            yield k, [list(c) for c in reversed(clusters[k:j + 1])], j - k + 1


MOVES: tuple[Move, ...] = (swap, relocate, split_off, merge, exchange, shift, reverse)
SMALL_MOVES: tuple[Move, ...] = (*MOVES, split)  # routes of up to SMALL items, and the fine descent
# the smoothed descent of a budget: one task (rover) moved first, the slowest moves to score
SMOOTH_MOVES: tuple[Move, ...] = (split_off, relocate, exchange, swap, merge, split, shift, reverse)
SPLIT_UPTO = 6  # members: ``split`` divides clusters up to this size (2^(k−1) divisions)
CHEAP_MOVES: tuple[Move, ...] = (swap, relocate, merge)  # linear in the route's length
LARGE = 30  # tasks (rovers): beyond this the quick plan uses CHEAP_MOVES
SMALL = 8  # tasks (rovers): up to this many, the moves sweep until none helps (else SMALL_ROUNDS sweeps)
SMALL_ROUNDS = 2
LARGE_ROUNDS = 2  # improvement sweeps of the cheap moves


def apply(clusters: Clusters, change: Change) -> list[list[int]]:
    i, pieces, count = change
    return [list(c) for c in clusters[:i]] + pieces + [list(c) for c in clusters[i + count:]]


def local_search(route: R, fits: Fits, score: Callable[[R, Change], tuple[float, Any]],
                 accept: Callable[[R, Any], R], makespan: Callable[[R], float],
                 moves: Sequence[Move] = MOVES, rounds: int = 20,
                 stop: Callable[[], bool] | None = None) -> R:
    """First-improvement descent over ``moves``: ``score(route, change)`` → (makespan, candidate),
    ``accept(route, candidate)`` → the new route. Stops when no move helps, after ``rounds``
    improvements per move sweep, or when ``stop()`` says so (a time budget; asked before every
    change is scored, so that a budget ends within one score)."""
    for _ in range(rounds):
        improved = False
        for move in moves:
            begin: int | None = 0
            while begin is not None:  # after an improvement at cluster i, go on from i − 1
                clusters, at, begin = route.clusters, begin, None  # type: ignore[attr-defined]
                for change in move(clusters, fits, at):
                    if stop is not None and stop():  # before scoring: a fine score can take a while
                        return route
                    t, cand = score(route, change)
                    if t < makespan(route) - 1e-9:
                        route, improved, begin = accept(route, cand), True, max(change[0] - 1, 0)
                        break
        if not improved:
            break
    return route


def deadline(budget_ms: float | None, t0: float | None = None) -> Callable[[], bool] | None:
    """``stop()`` for a time budget of ``budget_ms`` from ``t0`` (perf_counter; default now), or None."""
    if budget_ms is None:
        return None
    end = (time.perf_counter() if t0 is None else t0) + budget_ms / 1e3
    return lambda: time.perf_counter() > end


def _quick_score(route: Any, change: Change) -> tuple[float, Any]:
    cand = route.replace(*change)
    return cand[0], cand


def _accept(route: Any, cand: Any) -> Any:
    return route.accept(cand)


def _makespan(route: Any) -> float:
    return float(route.makespan)


def quick_descent(route: R, fits: Fits, stop: Callable[[], bool] | None = None,
                  cheap: Sequence[Move] = CHEAP_MOVES) -> R:
    """``local_search`` with every change re-timed by ``route.replace`` (stops re-placed around it).
    Routes of more than ``LARGE`` items get the ``cheap`` moves only, in two rounds at most."""
    if sum(len(c) for c in route.clusters) > LARGE:  # type: ignore[attr-defined,misc]
        return local_search(route, fits, _quick_score, _accept, _makespan, moves=cheap, rounds=LARGE_ROUNDS,
                            stop=stop)
    size = sum(len(c) for c in route.clusters)  # type: ignore[attr-defined,misc]
    rounds = 20 if size <= SMALL or stop is not None else SMALL_ROUNDS
    moves = SMALL_MOVES if size <= SMALL else MOVES
    return local_search(route, fits, _quick_score, _accept, _makespan, moves=moves, rounds=rounds, stop=stop)


def remembered(finish: Callable[[R], R]) -> Callable[[R], R]:
    """``finish`` remembering its result per route (clusters and stops): the exhaustive search,
    the fine descent's sweeps and the iterated search place the same quick routes again."""
    seen: dict[tuple, R] = {}

    def cached(r: R) -> R:
        key = (tuple(map(tuple, r.clusters)), tuple(r.positions))  # type: ignore[attr-defined]
        got = seen.get(key)
        if got is None:
            got = seen[key] = finish(r)
        return got
    return cached


def fine_descent(route: R, fits: Fits, rebuild: Callable[[list[list[int]]], R], finish: Callable[[R], R],
                 stop: Callable[[], bool] | None = None, slack: float = 0.15,
                 moves: Sequence[Move] | None = None) -> R:
    """``local_search`` with every change scored on the final placement: ``finish(rebuild(clusters))``.
    Changes whose quick route ``rebuild(clusters)`` is more than ``slack`` slower than the route
    are not placed finely (the fine placement rarely gains more)."""
    def score(r: R, change: Change) -> tuple[float, R | None]:
        quick = rebuild(apply(r.clusters, change))  # type: ignore[attr-defined]
        if _makespan(quick) > _makespan(r) * (1 + slack):
            return math.inf, None
        cand = finish(quick)
        return _makespan(cand), cand
    if moves is None:
        moves = SMALL_MOVES if sum(len(c) for c in route.clusters) <= SMALL else MOVES  # type: ignore[attr-defined,misc]
    return local_search(route, fits, score, lambda r, cand: cand, _makespan, moves=moves, stop=stop)


def perturb(clusters: Clusters, fits: Fits, rng: Any, strength: int = 2, window: int = 6) -> list[list[int]]:
    """``strength`` random changes inside one random window of consecutive clusters (the kick of
    the iterated local search)."""
    out = [list(c) for c in clusters]
    if not out:
        return out
    lo = rng.randrange(max(len(out) - window + 1, 1))
    for _ in range(strength):
        hi = min(lo + window, len(out))
        changes = [ch for move in MOVES for ch in move(out[lo:hi], fits, 0)]
        if not changes:
            break
        i, pieces, count = rng.choice(changes)
        out = apply(out, (lo + i, pieces, count))
    return out


def iterated_search(best: R, fits: Fits, rebuild: Callable[[list[list[int]]], R],
                    finish: Callable[[R], R], rng: Any, stop: Callable[[], bool],
                    max_fails: int) -> R:
    """Anytime improvement: kick the current route (``perturb``), descend on the quick placement,
    place finely (``finish``), keep the best route seen. Runs until ``stop()`` or ``max_fails``
    kicks in a row without a new best; the sequence of kicks depends only on ``rng``."""
    current, fails = best, 0
    while fails < max_fails and not stop():
        clusters = perturb(current.clusters, fits, rng, strength=1 + rng.randrange(3))  # type: ignore[attr-defined]
        cand = quick_descent(rebuild(clusters), fits, stop)
        if stop():
            break
        cand = finish(cand)
        if _makespan(cand) < _makespan(best) - 1e-9:
            best, current, fails = cand, cand, 0
            continue
        fails += 1
        # walk on from near-best routes so that the kicks can chain; restart from the best otherwise
        current = cand if _makespan(cand) <= _makespan(best) * 1.01 else best
    return best
