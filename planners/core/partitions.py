"""Every ordered partition of a few items into stops: the exhaustive search of tiny problems.

There are 1, 3, 13, 75, 541 ordered partitions of 1–5 items (the Fubini numbers), so up to 5
tasks (rovers) a planner can score them all on its quick placement and place the best few
finely; ``planners.core.exact`` places them all by constrained optimisation instead.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator, Sequence
from typing import Protocol, TypeVar


class _Timed(Protocol):
    makespan: float


R = TypeVar("R", bound=_Timed)


def set_partitions(items: Sequence[int]) -> Iterator[list[list[int]]]:
    """Every partition of ``items`` into non-empty blocks (each once)."""
    if not items:
        yield []
        return
    first, rest = items[0], items[1:]
    for part in set_partitions(rest):
        yield [[first], *part]
        for j in range(len(part)):
            yield [*part[:j], [first, *part[j]], *part[j + 1:]]


def ordered_partitions(n: int) -> Iterator[list[list[int]]]:
    """Every ordered partition of 0..n-1 into stops (the Fubini number of them: 1, 3, 13, 75, 541)."""
    for part in set_partitions(list(range(n))):
        for perm in itertools.permutations(part):
            yield [list(b) for b in perm]


def ranked_partitions(n: int, fits: Callable[[Sequence[int]], bool], rebuild: Callable[[list[list[int]]], R],
                      keep: int) -> list[R]:
    """The routes ``rebuild(clusters)`` of the ``keep`` fastest ordered partitions of n items whose
    clusters ``fits``, fastest first (ties in enumeration order)."""
    feasible: dict[tuple[int, ...], bool] = {}

    def ok(c: list[int]) -> bool:
        key = tuple(c)
        if key not in feasible:
            feasible[key] = fits(c)
        return feasible[key]

    scored: list[tuple[float, int, R]] = []
    for i, clusters in enumerate(ordered_partitions(n)):
        if all(ok(c) for c in clusters):
            r = rebuild(clusters)
            scored.append((r.makespan, i, r))
    scored.sort(key=lambda s: (s[0], s[1]))
    return [r for _, _, r in scored[:keep]]


def best_partition(n: int, fits: Callable[[Sequence[int]], bool], rebuild: Callable[[list[list[int]]], R],
                   finish: Callable[[R], R], keep: int) -> R | None:
    """Every ordered partition of n items whose clusters ``fits``, each scored on its quick route
    ``rebuild(clusters)``; the ``keep`` fastest are placed finely (``finish``) and the fastest
    of those returned (None when no partition fits)."""
    best: R | None = None
    for r in ranked_partitions(n, fits, rebuild, keep):
        cand = finish(r)
        if best is None or cand.makespan < best.makespan:
            best = cand
    return best
