"""Open-space deployment (dissertation ch. 4): the two-cluster optimum and the path generator.

Vocabulary follows the chapter: tasks are grouped into clusters P_ω; the carrier stops once
per cluster at a deployment point q_ω, unloads, and the cluster's rovers fly to their tasks.
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Sequence

from planners.core.clustering import Divider, divide_cluster
from planners.core.geometry import compass_search
from planners.core.moves import (
    SMOOTH_MOVES,
    deadline,
    fine_descent,
    iterated_search,
    merge,
    quick_descent,
    relocate_nearest,
    remembered,
)
from planners.core.partitions import best_partition
from planners.core.plan import Plan
from planners.core.problem import DeployProblem, PlanningError, Point2, refuse_obstacles
from planners.core.search import merge_neighbours, reorder, split_loop, swap_neighbours
from planners.core.trace import Trace, untraced
from planners.deploy.build import build_plan
from planners.deploy.cluster import DeployInstance, max_range_point
from planners.deploy.path import PathBuilder, Route
from planners.deploy.polish import smooth
from planners.deploy.stops import search_class, stop_cost
from planners.deploy.two_task import plan_two_tasks


def lee_clusters(problem: DeployProblem, improve: bool = True, t0: float | None = None,
                 tiny_search: bool = True, trace: Trace = untraced,
                 ) -> tuple[list[list[int]], list[Point2], float]:
    """Algorithm 4.1–4.2: divide until every cluster fits d_deploy, then the split/swap/merge loop
    that keeps the fastest path; with ``improve``, then re-sequence, swap and merge clusters while
    that helps (dividing again after them gained nothing on 240 instances of n = 3–1000: left out),
    then relocate tasks and place every stop finely. Returns clusters in visiting order, stops and
    makespan.
    ``tiny_search`` False leaves out the searches of tiny problems (every ordered partition, fine
    moves, smoothed stops up to 8 tasks): a quick plan for screening many (``plan_lee_screen``).
    ``trace`` is called with each phase's name and the makespan after it (``bench/phases.py``)."""
    inst = DeployInstance(problem)
    builder = PathBuilder(inst)
    n = len(inst.pts)
    if n == 0:
        return [], [], 0.0

    route = _divided(builder, improve, trace)

    # The loop re-placed stops only around each change; place every stop afresh, finely, and
    # keep whichever of the two routes is faster; then polish every stop (routes of any length).
    small = n <= FINE_UPTO
    gated = n if tiny_search else math.inf  # the size the searches of tiny problems go by (without: none)

    def place_finely(r: Route) -> Route:
        r = _fresh(builder, r)
        if not improve:
            return r
        if n >= BATCH_FROM:  # one sweep: long routes with numpy, short ones stop by stop
            return _polish_long(builder, r, COARSE_TOL) if len(r.clusters) >= BATCH_STOPS else (
                _polish(builder, r, 1, COARSE_TOL))
        return _polish(builder, r, 3 if small else 2, 1e-3 if small else COARSE_TOL)

    finish = remembered(place_finely)

    @remembered
    def smoothed(r: Route) -> Route:  # short routes: also on the smoothed makespan
        return smooth(builder, finish(r)) if gated <= SMOOTH_UPTO else finish(r)

    if not improve:
        best = finish(route)
        trace("final placement", best.makespan)
        return best.clusters, best.positions, best.makespan
    stop = deadline(problem.budget_ms, t0)
    # group and order moves (planners.core.moves), scored on the quick placement ...
    def nearness(task: int, cluster: Sequence[int]) -> float:
        c, p = inst.geometry(cluster).center, inst.pts[task]
        return (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2

    keep = next(k for upto, k in QD_KEEP if n <= upto)
    moved = quick_descent(route, inst.fits_quick, cheap=(relocate_nearest(nearness, keep), merge))
    trace("relocate and merge", moved.makespan)
    best = finish(moved)
    if small and moved is not route:  # today's plan too (large: the moves' route alone is polished)
        today = finish(route)
        best = today if today.makespan < best.makespan else best
    trace("final placement", best.makespan)
    if gated <= EXHAUSTIVE_UPTO:  # tiny: every ordered partition too
        every = best_partition(n, inst.fits_quick, builder.route, finish, EXHAUSTIVE_KEEP)
        best = every if every is not None and every.makespan < best.makespan else best
    if gated <= FINE_MOVES_UPTO or stop is not None:  # ... and on the final placement
        best = fine_descent(best, inst.fits_quick, builder.route, finish,
                                stop if gated > FINE_MOVES_UPTO else None,
                                slack=0.15 if stop is None and gated > EVERY_FINE_UPTO else math.inf)
    quick = best
    if stop is not None and gated <= SMOOTH_UPTO:  # a budget: the moves scored on the smoothed stops first
        best = fine_descent(best, inst.fits_quick, builder.route, smoothed, stop, slack=math.inf,
                            moves=SMOOTH_MOVES)
    if stop is not None:  # anytime: iterated local search until the budget
        best = iterated_search(best, inst.fits_quick, builder.route, smoothed,
                               random.Random(problem.seed), stop, max_fails=ILS_PATIENCE * n)
    if gated <= SMOOTH_UPTO:  # timed as the plan will fly (build_plan snaps a stop millimetres on)
        cands = (smooth(builder, best), smooth(builder, quick), quick) if stop is not None else (
            smooth(builder, best), quick)
        best = min(cands, key=lambda r: build_plan(problem, "lee", r.clusters, r.positions).makespan)
    trace("tiny-problem and budget searches", best.makespan)
    return best.clusters, best.positions, best.makespan


def _divided(builder: PathBuilder, improve: bool, trace: Trace) -> Route:
    """Algorithm 4.1 (divide until every cluster fits d_deploy) and 4.2 (the split/swap/merge loop),
    then with ``improve`` up to two rounds of re-sequencing, swapping and merging while they help."""
    inst, start, n = builder.inst, builder.start, len(builder.inst.pts)
    # Initial clustering (Algorithm 4.1): divide until every cluster fits d_deploy.
    clusters: list[list[int]] = [list(range(n))]
    idx = 0
    while idx < len(clusters):
        if not inst.fits(clusters[idx]):
            prev = start if idx == 0 else inst.geometry(clusters[idx - 1]).center
            near, far = divide_cluster(clusters[idx], inst.pts, (*prev, 0.0))
            clusters[idx: idx + 1] = [near, far]
        else:
            idx += 1
    divider = Divider(inst.pts)  # the split loop divides the same clusters again after a change

    def divide(route: Route, idx: int) -> tuple[list[int], list[int]]:
        prev = start if idx == 0 else route.positions[idx - 1]
        return divider(route.clusters[idx], (*prev, 0.0))

    tried: set = set()
    route = split_loop(builder.route(clusters), divide, tried)  # Algorithm 4.2
    trace("dissertation", route.makespan)
    for _ in range(2 if improve else 0):  # improvement search beyond the dissertation
        better = reorder(route, [g.center for g in route.geos], start, builder.route)
        trace("reorder", min(better.makespan, route.makespan))
        better = merge_neighbours(swap_neighbours(better), inst.fits_quick)
        trace("swap and merge", min(better.makespan, route.makespan))
        if better.makespan >= route.makespan - 1e-9:
            break
        route = better
    return route


def _fresh(builder: PathBuilder, r: Route) -> Route:
    """``r`` or its clusters' stops placed afresh, finely: whichever is faster."""
    fresh = builder.route(r.clusters, fine=True)
    return fresh if fresh.makespan <= r.makespan else r


FINE_MOVES_UPTO = 8  # tasks: up to this many, every move is also scored on fine, polished stops
EXHAUSTIVE_UPTO = 5  # up to this many, every ordered partition is scored on the quick placement ...
EXHAUSTIVE_KEEP = 6  # ... and this many of the fastest placed finely
EVERY_FINE_UPTO = 5  # up to this many, the fine descent places every change finely (no slack)
SMOOTH_UPTO = 8  # tasks: up to this many, the final stops are re-placed on the smoothed makespan
# (up to n tasks, k): the tasks of a cluster nearest its neighbour that the quick descent offers to it
# (big clusters of big problems: each offer costs an enclosing circle)
QD_KEEP = ((60, 3), (300, 1), (math.inf, 0))
FINE_UPTO = 12  # tasks: up to this many, the polish steps down to 1 mm and today's route is polished too
COARSE_TOL = 5e-2  # m: the polish's last step on larger problems (5 cm of carrier drive: ~3 ms)
ILS_PATIENCE = 20  # kicks per task without a new best before the anytime search gives up


def _polish(builder: PathBuilder, route: Route, sweeps: int = 3, tol: float = 1e-3) -> Route:
    """Improvement beyond the dissertation: move each stop on its own, with every other stop fixed,
    wherever the whole route gets faster and the stop still serves its cluster within d_deploy
    (a compass search on the exact time model, 8 directions, halving steps). The chapter's rules
    place early stops for the shortest drive and the last two by eq. 4.20; this trades the two
    against each other across the whole route. After the first sweep only stops with a moved
    neighbour (two either side) are searched again."""
    todo = set(range(len(route.clusters)))
    for _ in range(sweeps):
        before = route.makespan
        moved: set[int] = set()
        for k in sorted(todo):
            was = route.positions[k]
            route = _polish_stop(builder, route, k, tol)
            if route.positions[k] != was:
                moved.add(k)
        if route.makespan >= before - 1e-6:
            break
        todo = {j for k in moved for j in range(k - 2, k + 3) if 0 <= j < len(route.clusters)}
    return route


def _polish_stop(builder: PathBuilder, route: Route, k: int, tol: float) -> Route:
    """``route`` with stop k searched (``_polish``), every other stop fixed."""
    cost = stop_cost(builder, route, k)
    best = route.makespan
    x, y = route.positions[k]
    # a jump first: the compass search cannot leave a stop where moving a little costs a
    # turn (e.g. a stop on the start); try the cluster's centre and its point nearest the
    # carrier's line to the next stop
    prev = builder.start if k == 0 else route.positions[k - 1]
    nxt = route.positions[k + 1] if k + 1 < len(route.positions) else route.geos[k].center
    for cand in (route.geos[k].center, max_range_point(prev, route.geos[k], nxt)):
        t = cost(*cand)
        if t < best - 1e-9:
            best, (x, y) = t, cand
    x, y, best = compass_search(cost, x, y, best, max(builder.inst.d / 4, 0.05), tol)
    return route.moved(k, (x, y)) if (x, y) != route.positions[k] else route


def _polish_long(builder: PathBuilder, route: Route, tol: float) -> Route:
    """One sweep of ``_polish`` for long routes, with numpy: every third stop at once
    (``planners.deploy.stops``: stops three apart share no hop), the three classes in turn, each
    class's moves kept when the route re-timed exactly is faster (else one at a time, each on
    the exact cost); then the last two stops one at a time."""
    n = len(route.clusters)
    for c in range(BATCH_STRIDE):
        ks = list(range(c, n - 2, BATCH_STRIDE))
        new = search_class(builder, route, ks, tol) if ks else {}
        if not new:
            continue
        cand = route.with_stops(new)
        if cand.makespan < route.makespan - 1e-9:
            route = cand
            continue
        for k, q in new.items():
            if stop_cost(builder, route, k)(*q) < route.makespan - 1e-9:
                route = route.moved(k, q)
    for k in range(max(n - 2, 0), n):
        route = _polish_stop(builder, route, k, tol)
    return route


BATCH_STRIDE = 3  # stops: moving stop k changes the hops k, k + 1 and the turn at k + 1
BATCH_FROM = 61  # tasks: from this many on, the final polish sweeps once ...
BATCH_STOPS = 40  # ... and a route of this many stops has a class of stops searched at once


def plan_lee(problem: DeployProblem, tiny_search: bool = True) -> Plan:
    """The dissertation's deployment path generator (ch. 4.4), planner name ``lee``."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "lee")
    if len(problem.rover_ids()) < len(problem.tasks):
        raise PlanningError(f"{len(problem.tasks)} tasks need as many rovers, only "
                            f"{len(problem.rover_ids())} on the carrier")
    clusters, positions, _ = lee_clusters(problem, t0=t0, tiny_search=tiny_search)
    plan = build_plan(problem, "lee", clusters, positions)
    if len(problem.tasks) == 2:  # where it applies, the two-task optimum of ch. 4.3 (jointly placed stops)
        two = plan_two_tasks(problem)
        if two.makespan < plan.makespan:
            index = {t.id: i for i, t in enumerate(problem.tasks)}
            two_clusters: list[list[int]] = []
            for s in two.stops:
                tasks = [leg.task for leg in s.rovers]
                if None in tasks:
                    raise PlanningError("the two-task plan has a rover leg without a task")
                two_clusters.append([index[t] for t in tasks if t is not None])
            plan = build_plan(problem, "lee", two_clusters,
                              [(s.position[0], s.position[1]) for s in two.stops])
    plan.compute_ms = (time.perf_counter() - t0) * 1e3
    return plan


def plan_lee_screen(problem: DeployProblem) -> Plan:
    """``lee`` without the searches of tiny problems: tens of times cheaper on a few tasks, within a
    few per cent; the teams allocation screens its candidate shares with it
    (``planners.SCREEN_PLANNERS``)."""
    return plan_lee(problem, tiny_search=False)
