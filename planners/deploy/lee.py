"""Open-space deployment (dissertation ch. 4): the two-cluster optimum and the path generator.

Vocabulary follows the chapter: tasks are grouped into clusters P_ω; the carrier stops once
per cluster at a deployment point q_ω, unloads, and the cluster's rovers fly to their tasks.
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Callable, Sequence

from planners.core.clustering import divide_cluster
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
from planners.core.timing import carrier_hop, carrier_step, leg_time
from planners.deploy.build import build_plan
from planners.deploy.cluster import DeployInstance, max_range_point
from planners.deploy.path import PathBuilder, Route
from planners.deploy.polish import smooth
from planners.deploy.two_task import plan_two_tasks


def lee_clusters(problem: DeployProblem, improve: bool = True,
                 t0: float | None = None) -> tuple[list[list[int]], list[Point2], float]:
    """Algorithm 4.1–4.2: divide until every cluster fits d_deploy, then the split/swap/merge loop
    that keeps the fastest path; with ``improve``, then re-sequence and merge clusters and run
    the loop again while that helps. Returns clusters in visiting order, stops and makespan."""
    inst = DeployInstance(problem)
    builder = PathBuilder(inst)
    start = builder.start
    n = len(inst.pts)
    if n == 0:
        return [], [], 0.0

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
    def divide(route: Route, idx: int) -> tuple[list[int], list[int]]:
        prev = start if idx == 0 else route.positions[idx - 1]
        return divide_cluster(route.clusters[idx], inst.pts, (*prev, 0.0))

    tried: set = set()
    route = split_loop(builder.route(clusters), divide, tried)  # Algorithm 4.2
    for _ in range(2 if improve else 0):  # improvement search beyond the dissertation
        better = reorder(route, [g.center for g in route.geos], start, builder.route)
        better = merge_neighbours(swap_neighbours(better), inst.fits_quick)
        better = split_loop(better, divide, tried)
        if better.makespan >= route.makespan - 1e-9:
            break
        route = better

    # The loop re-placed stops only around each change; place every stop afresh, finely, and
    # keep whichever of the two routes is faster; then polish every stop (routes of any length).
    small = n <= FINE_UPTO

    def place_finely(r: Route) -> Route:
        r = _fresh(builder, r)
        sweeps = 3 if small else 2 if n <= 60 else 1
        return _polish(builder, r, sweeps, 1e-3 if small else COARSE_TOL) if improve else r

    finish = remembered(place_finely)

    @remembered
    def smoothed(r: Route) -> Route:  # short routes: also on the smoothed makespan
        return smooth(builder, finish(r)) if n <= SMOOTH_UPTO else finish(r)

    if not improve:
        best = finish(route)
        return best.clusters, best.positions, best.makespan
    stop = deadline(problem.budget_ms, t0)
    # group and order moves (planners.core.moves), scored on the quick placement ...
    def nearness(task: int, cluster: Sequence[int]) -> float:
        c, p = inst.geometry(cluster).center, inst.pts[task]
        return (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2

    keep = next(k for upto, k in QD_KEEP if n <= upto)
    moved = quick_descent(route, inst.fits_quick, cheap=(relocate_nearest(nearness, keep), merge))
    best = finish(moved)
    if small and moved is not route:  # today's plan too (large: the moves' route alone is polished)
        today = finish(route)
        best = today if today.makespan < best.makespan else best
    if n <= EXHAUSTIVE_UPTO:  # tiny: every ordered partition too
        every = best_partition(n, inst.fits_quick, builder.route, finish, EXHAUSTIVE_KEEP)
        best = every if every is not None and every.makespan < best.makespan else best
    if n <= FINE_MOVES_UPTO or stop is not None:  # ... and on the final placement
        best = fine_descent(best, inst.fits_quick, builder.route, finish,
                                stop if n > FINE_MOVES_UPTO else None,
                                slack=0.15 if stop is None and n > EVERY_FINE_UPTO else math.inf)
    quick = best
    if stop is not None and n <= SMOOTH_UPTO:  # a budget: the moves scored on the smoothed stops first
        best = fine_descent(best, inst.fits_quick, builder.route, smoothed, stop, slack=math.inf,
                            moves=SMOOTH_MOVES)
    if stop is not None:  # anytime: iterated local search until the budget
        best = iterated_search(best, inst.fits_quick, builder.route, smoothed,
                               random.Random(problem.seed), stop, max_fails=ILS_PATIENCE * n)
    if n <= SMOOTH_UPTO:  # timed as the plan will fly (build_plan snaps a stop millimetres on)
        cands = (smooth(builder, best), smooth(builder, quick), quick) if stop is not None else (
            smooth(builder, best), quick)
        best = min(cands, key=lambda r: build_plan(problem, "lee", r.clusters, r.positions).makespan)
    return best.clusters, best.positions, best.makespan


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


_TAU = 2.0 * math.pi


def _stop_cost(builder: PathBuilder, r: Route, k: int) -> Callable[[float, float], float]:
    """Makespan of route ``r`` with stop k moved to (x, y), the others kept, or inf where a task of
    stop k is out of reach: only the legs into k and k + 1 and the turn at k + 1 change; later
    stops shift in time by the same amount. The polish calls it
    thousands of times: the hops are ``planners.core.timing.carrier_step``."""
    b, pos, unload, d2max = builder, r.positions, builder.unload, builder.inst.d ** 2
    c = b.carrier
    w = c.turn_rate
    rover = b.rover
    rows = [b.inst.pts[i] for i in r.clusters[k]]
    rows2 = [(x, y, z * z) for x, y, z in rows]
    if k == 0:
        (px, py), t0, h0 = b.start, 0.0, b.inst.problem.heading
    else:
        (px, py), t0, h0 = pos[k - 1], r.arrive[k - 1] + unload, r.heading[k - 1]
    head = r.head[k - 1] if k else 0.0  # stops before k are not affected
    n = len(pos)
    nx1 = ny1 = 0.0
    done1 = arrive1 = 0.0
    if k + 1 < n:
        (nx1, ny1), done1, arrive1 = pos[k + 1], r.done[k + 1], r.arrive[k + 1]
    # the hop k + 1 → k + 2 keeps its length; only the turn at k + 1 depends on stop k
    h12: float | None = None
    hop12 = tail2 = arrive2 = 0.0
    if k + 2 < n:
        qx, qy = pos[k + 2]
        if (qx - nx1) ** 2 + (qy - ny1) ** 2 > 1e-18:
            h12 = math.atan2(qy - ny1, qx - nx1)
            hop12 = carrier_hop(pos[k + 1], pos[k + 2], h12, c)[0]  # travel only (no turn)
        tail2, arrive2 = r.tail[k + 2], r.arrive[k + 2]

    def cost(x: float, y: float) -> float:
        far = 0.0
        for tx, ty, z2 in rows2:
            e = (tx - x) ** 2 + (ty - y) ** 2 + z2
            if e > far:
                far = e
        if far > d2max:
            return math.inf
        dt, h = carrier_step(x - px, y - py, h0, c)
        t = t0 + dt + unload
        worst = max(head, t + leg_time(math.sqrt(far), rover))
        if k + 1 < n:
            dt, h = carrier_step(nx1 - x, ny1 - y, h, c)
            t1 = t + dt  # new arrival at k + 1
            worst = max(worst, done1 + (t1 - arrive1))
            if k + 2 < n:
                dt = hop12
                if h12 is not None and w is not None:
                    turn = (h12 - h) % _TAU
                    dt += min(turn, _TAU - turn) / w
                elif h12 is None:
                    dt = 0.0
                worst = max(worst, tail2 + (t1 + unload + dt - arrive2))
        return worst

    return cost


def _polish(builder: PathBuilder, route: Route, sweeps: int = 3, tol: float = 1e-3) -> Route:
    """Improvement beyond the dissertation: move each stop on its own, with every other stop fixed,
    wherever the whole route gets faster and the stop still serves its cluster within d_deploy
    (a compass search on the exact time model, 8 directions, halving steps). The chapter's rules
    place early stops for the shortest drive and the last two by eq. 4.20; this trades the two
    against each other across the whole route. After the first sweep only stops with a moved
    neighbour (two either side) are searched again."""
    inst = builder.inst
    todo = set(range(len(route.clusters)))
    for _ in range(sweeps):
        before = route.makespan
        moved: set[int] = set()
        for k in sorted(todo):
            cost = _stop_cost(builder, route, k)
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
            x, y, best = compass_search(cost, x, y, best, max(inst.d / 4, 0.05), tol)
            if (x, y) != route.positions[k]:
                route = route.moved(k, (x, y))
                moved.add(k)
        if route.makespan >= before - 1e-6:
            break
        todo = {j for k in moved for j in range(k - 2, k + 3) if 0 <= j < len(route.clusters)}
    return route


def plan_lee(problem: DeployProblem) -> Plan:
    """The dissertation's deployment path generator (ch. 4.4), planner name ``lee``."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "lee")
    if len(problem.rover_ids()) < len(problem.tasks):
        raise PlanningError(f"{len(problem.tasks)} tasks need as many rovers, only "
                            f"{len(problem.rover_ids())} on the carrier")
    clusters, positions, _ = lee_clusters(problem, t0=t0)
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
