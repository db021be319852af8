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
import random
import time
from collections.abc import Callable, Sequence

from planners.collect.instance import CollectInstance
from planners.collect.path import PathBuilder, Route
from planners.collect.polish import polish, smooth
from planners.collect.reach import Point2
from planners.collect.two import two_rover_route
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
    swap,
)
from planners.core.partitions import best_partition, ranked_partitions
from planners.core.plan import SNAP, Plan, RoverLeg, Stop
from planners.core.problem import CollectProblem, Vec3, refuse_obstacles
from planners.core.search import merge_neighbours, reorder, split_loop
from planners.core.timing import carrier_step, leg_time, retime
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
                if math.dist(inst.pts2[r], stop) > inst.radii[r] or not inst.fits([*b, r]):
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


def _stop_cost(route: Route, k: int) -> Callable[[float, float], float]:
    """Makespan of ``route`` with stop k moved to (x, y), the others kept, or inf outside I_β:
    the hops into k, k + 1 and k + 2 are re-timed, later stops by ``Route.end_from``. The compass
    search calls it thousands of times: the hops are ``planners.core.timing.carrier_step``."""
    b = route.b
    inst, c, rover, load = b.inst, b.carrier, b.rover, b.load
    members = route.clusters[k]
    rows = [(inst.pts2[i][0], inst.pts2[i][1], float(inst.radii[i]) ** 2, float(inst.heights2[i]))
            for i in members]
    (px, py), t0, h0 = route.state_before(k)
    n = len(route.positions)
    nxt = route.positions[k + 1:k + 3]
    ready = route.ready[k + 1:k + 3]

    def cost(x: float, y: float) -> float:
        far = 0.0
        for gx, gy, r2, z2 in rows:
            e = (x - gx) ** 2 + (y - gy) ** 2
            if e > r2:
                return math.inf
            if e + z2 > far:
                far = e + z2
        dt, h = carrier_step(x - px, y - py, h0, c)
        t = max(t0 + dt, leg_time(math.sqrt(far), rover)) + load
        qx, qy = x, y
        for (nx, ny), rd in zip(nxt, ready, strict=True):
            dt, h = carrier_step(nx - qx, ny - qy, h, c)
            t = max(t + dt, rd) + load
            qx, qy = nx, ny
        return route.end_from(k + len(nxt), t) if k + 1 < n else t

    return cost


def compass(builder: PathBuilder, route: Route, sweeps: int = 2, tol: float = 1e-3) -> Route:
    """Move each stop on its own inside its region I_β wherever the route gets faster (a compass
    search on the exact time model, 8 directions, halving steps down to ``tol`` m): the candidate
    points of eq. 5.13–5.16 miss the interior point where the carrier and the cluster's last rover
    arrive together. After the first sweep only stops with a moved neighbour are searched again."""
    inst = builder.inst
    todo = set(range(len(route.clusters)))
    for _ in range(sweeps):
        before = route.makespan
        moved: set[int] = set()
        for k in sorted(todo):
            cost = _stop_cost(route, k)
            best = route.makespan
            x, y = route.positions[k]
            step = max(float(min(inst.radii[i] for i in route.clusters[k])) / 4, 0.05)
            x, y, best = compass_search(cost, x, y, best, step, tol)
            if (x, y) != route.positions[k]:
                route = route.moved(k, (x, y))
                moved.add(k)
        if route.makespan >= before - 1e-6:
            break
        todo = {j for k in moved for j in range(k - 2, k + 3) if 0 <= j < len(route.clusters)}
    return route


def place_finely(builder: PathBuilder, r: Route, small: bool) -> Route:
    """The final placement of a route's stops: (small routes: afresh, finely, if faster) the polish
    of each stop with both neighbours known, then the compass search on eq. 5.2."""
    if small:
        fresh = builder.route(r.clusters, 2)
        r = fresh if fresh.makespan <= r.makespan else r
    r = polish(builder, r, sweeps=2 if small else 1, level=2 if small else 1)
    return compass(builder, r, tol=1e-3 if small else COARSE_TOL)


def screened(builder: PathBuilder, best: Route, smoothed: Callable[[Route], Route],
              stop: Callable[[], bool]) -> Route:
    """Tiny problems with a budget: every ordered partition ranked on the chapter's candidate
    placement (level 1; the quick placement can tie dozens of partitions on one slow rover), the
    ``SCREEN_KEEP`` fastest placed finely and on the smoothed makespan while the budget lasts."""
    inst = builder.inst
    if stop():
        return best
    ranked = ranked_partitions(len(inst.pts2), inst.fits, lambda c: builder.route(c, 1), SCREEN_KEEP)
    for r in ranked:
        if stop():
            break
        cand = smoothed(r)
        best = cand if cand.makespan < best.makespan else best
    return best


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


def lee_route(problem: CollectProblem, improve: bool = True, fine_upto: int = 12,
              t0: float | None = None, tiny_search: bool = True,
              trace: Trace = untraced) -> tuple[PathBuilder, Route]:
    """Algorithm 5.1–5.2, then (with ``improve``) re-sequencing, merging and handing rovers over
    while that helps, and a final fine placement of every stop with both neighbours known.
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
    route = split_loop(builder.route(_initial_clusters(builder)), divide, rejected, accept_ties=False)
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
    small = len(problem.rovers) <= fine_upto
    gated = len(problem.rovers) if tiny_search else math.inf  # the size the tiny problems' searches go by
    finish = remembered(lambda r: place_finely(builder, r, small))

    @remembered
    def smoothed(r: Route) -> Route:  # short routes: also on the smoothed makespan
        return smooth(builder, finish(r)) if gated <= SMOOTH_UPTO else finish(r)

    stop = deadline(problem.budget_ms, t0) if improve else None
    early = None  # a budget: tiny problems first screen every partition on finer stops (while it lasts)
    if stop is not None and gated <= EXHAUSTIVE_UPTO:
        early = screened(builder, route, smoothed, stop)
    if not improve:
        best = finish(route)
        trace("final placement", best.makespan)
    else:  # group and order moves (planners.core.moves), scored on the quick placement ...
        keep = next(k for upto, k in QD_KEEP if len(problem.rovers) <= upto)

        def nearness(rover: int, cluster: Sequence[int]) -> float:
            c, p = inst.region(cluster).center, inst.pts2[rover]
            return (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2

        moved = quick_descent(route, inst.fits, cheap=(swap, relocate_nearest(nearness, keep), merge))
        trace("swap, relocate and merge", moved.makespan)
        best = finish(moved)
        if small and moved is not route:  # (large routes: the moves' route alone is placed finely)
            today = finish(route)
            best = today if today.makespan < best.makespan else best
        trace("final placement", best.makespan)
        if gated <= EXHAUSTIVE_UPTO:  # tiny: every ordered partition too
            every = best_partition(len(problem.rovers), inst.fits, builder.route, finish, EXHAUSTIVE_KEEP)
            best = every if every is not None and every.makespan < best.makespan else best
            best = early if early is not None and early.makespan < best.makespan else best
        if gated <= FINE_MOVES_UPTO or stop is not None:  # ... and on the final stops
            best = fine_descent(best, inst.fits, builder.route, finish,
                                stop if gated > FINE_MOVES_UPTO else None,
                                slack=0.15 if stop is None and gated > EVERY_FINE_UPTO else math.inf)
    quick = best
    if stop is not None and gated <= SMOOTH_UPTO:  # a budget: the moves on smoothed stops first
        best = fine_descent(best, inst.fits, builder.route, smoothed, stop, slack=math.inf,
                            moves=SMOOTH_MOVES)
    if stop is not None:  # anytime: iterated local search until the budget
        best = iterated_search(best, inst.fits, builder.route, smoothed, random.Random(problem.seed), stop,
                               max_fails=ILS_PATIENCE * len(problem.rovers))
    route = smooth(builder, best) if gated <= SMOOTH_UPTO else best
    if gated <= SMOOTH_UPTO:  # timed as the plan will fly (its builder snaps and pulls
        # stops into reach: a nudged stop on top of the previous one has an arbitrary heading)
        cands = (route, smooth(builder, quick), quick) if stop is not None else (route, quick)
        route = min(cands, key=lambda r: build_collect_plan(problem, "lee", r.clusters, r.positions).makespan)
    if len(problem.rovers) == 2:
        two = two_rover_route(builder)  # the ch. 5.3 optimum, where it applies
        if two.makespan < route.makespan:
            route = compass(builder, two)
    trace("tiny-problem and budget searches", route.makespan)
    return builder, route


FINE_MOVES_UPTO = 8  # rovers: up to this many, every move is also scored on fine, polished stops
EXHAUSTIVE_UPTO = 5  # up to this many, every ordered partition is scored on the quick placement ...
EXHAUSTIVE_KEEP = 6  # ... and this many of the fastest placed finely
SCREEN_KEEP = 3  # with a budget: the partitions fastest on level-1 stops, re-placed on the smoothed makespan
EVERY_FINE_UPTO = 5  # up to this many, the fine descent places every change finely (no slack)
SMOOTH_UPTO = 8  # rovers: up to this many, the final stops are re-placed on the smoothed makespan
# (up to n rovers, k): the rovers of a cluster nearest its neighbour that the quick descent offers to it
QD_KEEP = ((200, 4), (math.inf, 2))
MOVE_ROVERS_UPTO = 200  # rovers: beyond, the loop does not hand rovers over (the quick descent does)
COARSE_TOL = 5e-2  # m: the compass search's last step on large routes (1 mm on small ones)


ILS_PATIENCE = 20  # kicks per rover without a new best before the anytime search gives up


def build_collect_plan(problem: CollectProblem, planner: str, clusters: Sequence[Sequence[int]],
                       positions: Sequence[Point2], compute_ms: float = 0.0) -> Plan:
    """Turn clusters and collection locations into a Plan timed by ``timing.retime``: each rover
    flies a straight 3D line from where it is to its meeting point on the ground."""
    stops: list[Stop] = []
    prev: Vec3 = problem.start
    for members, pos in zip(clusters, positions, strict=True):
        inside = _within_reach(problem, members, (float(pos[0]), float(pos[1])))
        here: Vec3 = _snap(problem, members, prev, inside)
        legs = [RoverLeg(rover=problem.rovers[i].id, path=[problem.rovers[i].position, here])
                for i in members]
        stops.append(Stop(position=here, carrier_path=[prev, here], rovers=legs))
        prev = here
    plan = Plan(kind="collect", planner=planner, start=problem.start, heading=problem.heading, stops=stops,
                compute_ms=compute_ms)
    return retime(plan, problem.carrier, problem.rover)


def _within_reach(problem: CollectProblem, members: Sequence[int], p: Point2) -> Vec3:
    """``p`` pulled inside every member's reach disc where rounding left it a hair outside
    (alternating projections; the discs intersect, so this converges to a point of I_β)."""
    x, y = p
    for _ in range(50):
        worst = 0.0
        for i in members:
            (gx, gy, z), r = problem.rovers[i].position, problem.rovers[i].range
            rho = math.sqrt(max(r * r - z * z, 0.0))
            d = math.hypot(x - gx, y - gy)
            if d > rho:
                worst = max(worst, d - rho)
                if d == 0.0 or rho == 0.0:
                    x, y = gx, gy
                else:
                    x, y = gx + (x - gx) * rho / d, gy + (y - gy) * rho / d
        if worst == 0.0:
            break
    return (x, y, 0.0)


def _snap(problem: CollectProblem, members: Sequence[int], prev: Vec3, here: Vec3) -> Vec3:
    """A stop a hair's breadth (< 1 cm) from the previous one is put exactly on it when every rover
    can still reach it: a hop of micrometres has an arbitrary heading once the plan's coordinates
    are rounded for JSON, and turning to it would cost real time."""
    if 0.0 < math.dist(prev[:2], here[:2]) < SNAP:
        snapped: Vec3 = (prev[0], prev[1], 0.0)
        if all(math.dist(problem.rovers[i].position, snapped) <= problem.rovers[i].range - 1e-5
               for i in members):
            return snapped
    return here


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
