"""The search after the greedy of Algorithm 6.3, shared by the deployment and collection graph
planners: the moves of the open-space planners (``planners.core.moves``: relocate, exchange,
split-off, split, merge, swap, shift, reverse; ``planners.core.search.reorder``) on a
``RoadmapRoute``, each change's stops chosen among the roadmap's nodes and polished, then new
roadmap nodes near the final stops (``planners.roadmap.refine``).

Only improvements are kept, and the caller keeps the greedy's plan when the search does not
beat it. With a time budget (``budget_ms``) the iterated local search runs until it is spent.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Sequence

from planners.core.driver import FINE_MOVES_UPTO, ILS_PATIENCE
from planners.core.moves import deadline, fine_descent, iterated_search, quick_descent, remembered
from planners.core.plan import Plan
from planners.core.search import reorder
from planners.roadmap.costs import RoadmapCosts
from planners.roadmap.refine import refine
from planners.roadmap.route import SEARCH_SHORTLIST, RoadmapRoute, RouteSpace


def search(route: RoadmapRoute, build: Callable[[Sequence[tuple[int, list[int]]]], Plan], greedy: Plan,
           budget_ms: float | None, seed: int, t0: float | None = None) -> Plan:
    """The search after the greedy: the moves on ``route`` (``improve``), new roadmap nodes near
    the stops (``refine``); with a budget, then the iterated local search until it is spent and
    the refinement of what it found. The fastest plan built (``build``), ``greedy`` included."""
    stop = deadline(budget_ms, t0)
    plan, route = refine(improve(route, stop), build, greedy)
    if stop is None or stop() or sum(len(c) for c in route.clusters) < 2:
        return plan
    space = route.space
    finish = remembered(lambda r: space.polish(r, SEARCH_SHORTLIST))
    better = iterated_search(route, space.fits, space.route, finish, random.Random(seed), stop,
                             max_fails=ILS_PATIENCE * sum(len(c) for c in route.clusters))
    if better.makespan < route.makespan - 1e-9:
        plan, _ = refine(better, build, plan, stop)
    return plan


def search_greedy(order: Sequence[tuple[int, Sequence[int]]], costs: RoadmapCosts, heading: float,
                  deploy: bool, build: Callable[[Sequence[tuple[int, list[int]]]], Plan], greedy: Plan,
                  budget_ms: float | None, seed: int, t0: float | None = None) -> Plan:
    """``search`` from the greedy's stops ``order`` ((node, members) in visiting order) and its
    plan ``greedy``: what both graph planners run after Algorithm 6.3."""
    space = RouteSpace(costs, heading, deploy=deploy)
    route = space.timed([list(m) for _, m in order], [n for n, _ in order], None, 0)
    return search(route, build, greedy, budget_ms, seed, t0)


def improve(route: RoadmapRoute, stop: Callable[[], bool] | None = None) -> RoadmapRoute:
    """The moves on ``route`` (the greedy's) until none makes it faster, each change's stops
    polished (``RouteSpace.polish``); as in the open-space planners, the quick descent always
    runs to its end and ``stop`` (a budget's deadline) bounds the fine descent of long routes."""
    space = route.space
    n = sum(len(c) for c in route.clusters)
    if n < 2:
        return space.polish(route)
    finish = remembered(lambda r: space.polish(r, SEARCH_SHORTLIST))
    best = finish(route)
    moved = quick_descent(route, space.fits)
    moved = reorder(moved, moved.positions, space.start, space.route)
    best = _faster(best, finish(moved))
    if n <= FINE_MOVES_UPTO or stop is not None:
        best = fine_descent(best, space.fits, space.route, finish, stop if n > FINE_MOVES_UPTO else None,
                            slack=0.15 if stop is None else math.inf)
    return best


def _faster(a: RoadmapRoute, b: RoadmapRoute) -> RoadmapRoute:
    return b if b.makespan < a.makespan - 1e-9 else a

