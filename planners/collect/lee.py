"""Open-space collection (dissertation ch. 5): clusters of rovers meet the carrier at one stop each.

Vocabulary follows the chapter: rovers are grouped into clusters P_γβ whose reach discs share a
region I_β (eq. 5.12, ``planners.collect.reach``); the carrier stops once per cluster at a collection
location q_γβ in I_β; every rover starts flying to its meeting point at t = 0 and the carrier waits
for the cluster's last rover, then loads (eq. 5.2). The makespan is the last stop's departure.

Algorithm 5.1 divides the rovers until every cluster has a common region; Algorithm 5.2 then
tries to divide each cluster, in both orders (SWAP_CLUSTERS), keeps the division when the path
gets faster and merges it back otherwise. GET_COLLECT_PATH places every cluster's stop in turn
(``PathBuilder.place``): the fast way scores the chapter's candidate points (the circles'
intersection points and the points of I_β nearest the carrier's line, eq. 5.13–5.16) on the time
model; ``planners.collect.convex`` solves the same placement as a constrained program.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

from planners.collect.build import build_collect_plan
from planners.collect.instance import CollectInstance
from planners.collect.path import PathBuilder, Route
from planners.collect.polish import compass, place_finely, smooth
from planners.collect.two import two_rover_route
from planners.core.clustering import divide_cluster
from planners.core.driver import search
from planners.core.moves import Move, merge, relocate_nearest, swap
from planners.core.plan import Plan
from planners.core.problem import CollectProblem, refuse_obstacles
from planners.core.search import merge_neighbours, reorder, split_loop
from planners.core.trace import Trace, untraced


def _move_rovers(builder: PathBuilder, route: Route) -> Route:
    """Beyond the dissertation: hand a rover over to the neighbouring cluster when it can reach that
    cluster's stop and the route gets faster (the divider's straight cut can misplace it)."""
    inst = builder.inst
    k = 0
    while k + 1 < len(route.clusters):
        moved = False
        for src, dst in ((k, k + 1), (k + 1, k)):
            a, b = route.clusters[src], route.clusters[dst]
            if len(a) < 2:
                continue
            stop = route.positions[dst]
            for r in list(a):
                # only rovers that reach the neighbour's present stop: that cluster keeps a stop
                if math.dist(inst.pts2[r], stop) > inst.rad[r] or not inst.fits([*b, r]):
                    continue
                pieces = [[x for x in a if x != r], [*b, r]]
                if src > dst:
                    pieces.reverse()
                cand = route.replace(k, pieces, count=2)
                if cand[0] < route.makespan - 1e-9:
                    route = route.accept(cand)
                    moved = True
                    break
            if moved:
                break
        if not moved:
            k += 1
    return route


class CollectSpace:
    """Collection's side of the search driver (``planners.core.driver.SearchSpace``): the quick
    placement of ch. 5.4 (``PathBuilder.route``), the final placement and the smoothed stops
    (``planners.collect.polish``), plans built by ``build_collect_plan``, the chapter's candidate
    placement (level 1) to rank tiny problems' partitions on, and the quick descent's moves (swaps,
    rovers handed to the neighbouring cluster, ``QD_KEEP`` nearest it, and merges)."""

    def __init__(self, problem: CollectProblem, builder: PathBuilder) -> None:
        self.problem, self.builder = problem, builder
        self.inst = inst = builder.inst
        self.size = len(problem.rovers)
        self.fits = inst.fits
        self.rebuild = builder.route
        keep = next(k for upto, k in QD_KEEP if self.size <= upto)
        # (the moves hold the instance, not this space: no reference cycle, so that a plan's caches
        # are freed when it returns, not by the garbage collector in a later plan's time)
        self.cheap: Sequence[Move] = (swap, relocate_nearest(nearness(inst), keep), merge)
        # long routes: a change's quick score leaves the stop before it in place (a third fewer
        # stops placed per score, and as good plans on 500-1000 rovers)
        builder.replace_before = self.size < QD_KEEP_BEFORE_FROM

    def finish(self, route: Route, small: bool, improve: bool) -> Route:
        return place_finely(self.builder, route, small)

    def smooth(self, route: Route) -> Route:
        return smooth(self.builder, route)

    def flown(self, route: Route) -> float:
        return build_collect_plan(self.problem, "lee", route.clusters, route.positions).makespan

    def ranking(self) -> Callable[[list[list[int]]], Route]:
        return lambda clusters: self.builder.route(clusters, 1)


def nearness(inst: CollectInstance) -> Callable[[Sequence[int]], Callable[[int], float]]:
    """``near(cluster)``: the key ranking rovers by their squared distance to ``cluster``'s power
    centre (the quick descent's ``relocate_nearest``)."""
    pts = inst.pts2

    def near(cluster: Sequence[int]) -> Callable[[int], float]:
        c = inst.region(cluster).center
        return lambda rover: (pts[rover][0] - c[0]) ** 2 + (pts[rover][1] - c[1]) ** 2
    return near


def _initial_clusters(builder: PathBuilder) -> list[list[int]]:
    """Algorithm 5.1, initial clustering: divide until every cluster has a common region."""
    inst = builder.inst
    clusters: list[list[int]] = [list(range(len(inst.pts2)))]
    idx = 0
    while idx < len(clusters):
        if not inst.fits(clusters[idx]):
            prev = builder.start if idx == 0 else inst.region(clusters[idx - 1]).center
            near, far = divide_cluster(clusters[idx], inst.pts2, prev)
            clusters[idx: idx + 1] = [near, far]
        else:
            idx += 1
    return clusters


def lee_route(problem: CollectProblem, improve: bool = True, t0: float | None = None,
              tiny_search: bool = True, trace: Trace = untraced) -> tuple[PathBuilder, Route]:
    """Algorithm 5.1–5.2, then (with ``improve``) re-sequencing, merging and handing rovers over
    while that helps, then the search driver (``planners.core.driver.search``: moves, the final
    fine placement of every stop with both neighbours known, the searches of tiny problems, a
    budget's anytime search) and, for two rovers, the ch. 5.3 optimum where it is faster.
    ``tiny_search`` False leaves out the searches of tiny problems (every ordered partition, fine
    moves, smoothed stops up to 8 rovers): a quick plan for screening many. ``trace`` is called
    with each phase's name and the makespan after it (``bench/phases.py``)."""
    inst = CollectInstance(problem)
    builder = PathBuilder(inst)
    if not problem.rovers:
        return builder, Route(builder, [], [], [])

    def divide(route: Route, idx: int) -> tuple[list[int], list[int]]:
        prev = builder.start if idx == 0 else route.positions[idx - 1]
        return divide_cluster(route.clusters[idx], inst.pts2, prev)  # Algorithm 3.1

    rejected: set[tuple] = set()
    # long routes: a division's score leaves the stop before it in place (as the quick descent's
    # changes do), which lets the screen (planners.collect.screen) rule most divisions out
    builder.replace_before = len(problem.rovers) < QD_KEEP_BEFORE_FROM
    route = split_loop(builder.route(_initial_clusters(builder)), divide, rejected, accept_ties=False)
    builder.replace_before = True
    trace("dissertation", route.makespan)
    for _ in range(3 if improve else 0):  # improvement search beyond the dissertation
        better = reorder(route, route.positions, builder.start, builder.route)
        trace("reorder", min(better.makespan, route.makespan))
        better = merge_neighbours(better, inst.fits)
        if len(problem.rovers) <= MOVE_ROVERS_UPTO:  # (larger: the quick descent's bounded relocate)
            better = _move_rovers(builder, better)
        trace("merge and move rovers", min(better.makespan, route.makespan))
        if better.makespan >= route.makespan - 1e-9:
            break
        route = better
    route = search(CollectSpace(problem, builder), route, improve=improve, budget_ms=problem.budget_ms, t0=t0,
                   seed=problem.seed, tiny_search=tiny_search, trace=trace)
    if len(problem.rovers) == 2:
        two = two_rover_route(builder)  # the ch. 5.3 optimum, where it applies
        if two.makespan < route.makespan:
            route = compass(builder, two)
            trace("two-rover optimum", route.makespan)
    return builder, route


# (up to n rovers, k): the rovers of a cluster nearest its neighbour that the quick descent offers to it
QD_KEEP = ((200, 4), (math.inf, 2))
MOVE_ROVERS_UPTO = 200  # rovers: beyond, the loop does not hand rovers over (the quick descent does)
QD_KEEP_BEFORE_FROM = 201  # rovers: from this many on, the search's changes keep the stop before them


def plan_collect_lee(problem: CollectProblem, tiny_search: bool = True) -> Plan:
    """The dissertation's collection path generator (ch. 5.4) with the fast meeting points; ``lee``."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "lee")
    _, route = lee_route(problem, t0=t0, tiny_search=tiny_search)
    ms = (time.perf_counter() - t0) * 1e3
    return build_collect_plan(problem, "lee", route.clusters, route.positions, ms)


def plan_collect_lee_screen(problem: CollectProblem) -> Plan:
    """``lee`` without the searches of tiny problems (``lee_route``'s ``tiny_search``): the teams
    allocation screens its candidate shares with it (``planners.SCREEN_PLANNERS``)."""
    return plan_collect_lee(problem, tiny_search=False)
