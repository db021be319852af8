"""Open-space deployment (dissertation ch. 4): the two-cluster optimum and the path generator.

Vocabulary follows the chapter: tasks are grouped into clusters P_ω; the carrier stops once
per cluster at a deployment point q_ω, unloads, and the cluster's rovers fly to their tasks.
"""

from __future__ import annotations

import itertools
import math
import random
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from planners.core.clustering import divide_cluster
from planners.core.geometry import compass_search, enclosing_ball, find_root, minimize_1d
from planners.core.moves import (
    deadline,
    fine_descent,
    iterated_search,
    merge,
    quick_descent,
    relocate_nearest,
)
from planners.core.plan import Plan, RoverLeg, Stop
from planners.core.problem import DeployProblem, PlanningError, Vec3, refuse_obstacles
from planners.core.search import merge_neighbours, reorder, split_loop, swap_neighbours
from planners.core.timing import RANGE_MARGIN, carrier_hop, carrier_step, leg_time, retime

Point2 = tuple[float, float]


@dataclass(frozen=True)
class ClusterGeometry:
    """Where a cluster can be served from.

    ``center`` is the ground point whose farthest task is nearest (a power-weighted enclosing
    circle, see planners.core.geometry), ``reach`` that farthest 3D distance, ``slack`` the radius
    of the disc around ``center`` from every point of which all tasks are within d_deploy
    (the disc of eq. 4.23: (Δd)² + z² = (d_deploy − π)² in the chapter's sphere form).
    """

    members: tuple[int, ...]
    center: Point2
    reach: float
    slack: float


class _Instance:
    """Per-problem caches: task coordinates and cluster geometry by membership."""

    def __init__(self, problem: DeployProblem) -> None:
        self.problem = problem
        self.pts: list[Vec3] = [t.position for t in problem.tasks]
        self.range = problem.deploy_range
        self.d = max(problem.deploy_range - RANGE_MARGIN, 0.0)  # planned flights stay inside this
        self._geo: dict[tuple[int, ...], ClusterGeometry] = {}
        for i, p in enumerate(self.pts):
            if p[2] > self.range or p[2] < 0:
                raise PlanningError(
                    f"task {problem.tasks[i].id} at height {p[2]:g} m cannot be reached with a "
                    f"deploy range of {problem.deploy_range:g} m")

    def geometry(self, members: Sequence[int]) -> ClusterGeometry:
        key = tuple(sorted(members))
        g = self._geo.get(key)
        if g is None:
            pts = [self.pts[i] for i in key]
            ball = enclosing_ball([(p[0], p[1]) for p in pts], [p[2] ** 2 for p in pts])
            c = (ball.center[0], ball.center[1])
            slack = max(0.0, min(math.sqrt(max(self.d**2 - p[2] ** 2, 0.0))
                                 - math.hypot(p[0] - c[0], p[1] - c[1]) for p in pts))
            g = ClusterGeometry(key, c, ball.radius, slack)
            self._geo[key] = g
        return g

    def fits_quick(self, members: Sequence[int]) -> bool:
        """``fits`` behind a cheaper test: the first and last tasks must be within 2·d_deploy."""
        return math.dist(self.pts[members[0]], self.pts[members[-1]]) <= 2 * self.range and self.fits(members)

    def fits(self, members: Sequence[int]) -> bool:
        """Can one stop serve every task of the cluster within d_deploy (Algorithm 4.1's test)?"""
        if len(members) > 3:  # cheap necessary test before the enclosing circle: two tasks farther
            xs = [self.pts[i][0] for i in members]  # apart than 2·d_deploy never share a stop
            ys = [self.pts[i][1] for i in members]
            if max(xs) - min(xs) > 2 * self.range or max(ys) - min(ys) > 2 * self.range:
                return False
        return self.geometry(members).reach <= self.range

    def reach_from(self, p: Point2, members: Sequence[int]) -> float:
        """Longest rover flight from ground point ``p`` to the cluster's tasks (eq. 4.5 numerator)."""
        x, y = p
        pts = self.pts
        worst = 0.0
        for i in members:
            q = pts[i]
            d2 = (q[0] - x) ** 2 + (q[1] - y) ** 2 + q[2] * q[2]
            if d2 > worst:
                worst = d2
        return math.sqrt(worst)

    def feasible_from(self, a: Point2, b: Point2, members: Sequence[int]) -> float:
        """Smallest s in [0, 1] such that a + s·(b − a) serves every task (b must serve them)."""
        s_lo = 0.0
        dx, dy = b[0] - a[0], b[1] - a[1]
        qa = dx * dx + dy * dy
        for i in members:
            x, y, z = self.pts[i]
            r2 = max(self.d**2 - z * z, 0.0)
            ex, ey = a[0] - x, a[1] - y
            qc = ex * ex + ey * ey - r2
            if qc <= 0:
                continue
            if qa == 0:
                return 1.0
            qb = 2 * (dx * ex + dy * ey)
            disc = qb * qb - 4 * qa * qc
            s1 = (-qb - math.sqrt(max(disc, 0.0))) / (2 * qa)
            s_lo = max(s_lo, s1)
        return min(max(s_lo, 0.0), 1.0)


def _lerp(a: Point2, b: Point2, s: float) -> Point2:
    return (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]))


def max_range_point(prev: Point2, geo: ClusterGeometry, nxt: Point2) -> Point2:
    """Deployment point of an early cluster (eq. 4.21–4.23): at the rovers' maximum range,
    moved from the cluster centre toward the carrier's line to the next cluster.

    The point is the one of the disc (centre, slack) nearest the line prev → next: on the
    perpendicular through the centre (4.22) at Δd = slack (4.23), or the foot of the
    perpendicular when the line already crosses the disc.
    """
    cx, cy = geo.center
    dx, dy = nxt[0] - prev[0], nxt[1] - prev[1]
    n2 = dx * dx + dy * dy
    if n2 < 1e-18:
        fx, fy = prev
    else:
        s = ((cx - prev[0]) * dx + (cy - prev[1]) * dy) / n2
        fx, fy = prev[0] + s * dx, prev[1] + s * dy  # foot of the perpendicular (4.21 ∩ 4.22)
    ox, oy = fx - cx, fy - cy
    off = math.hypot(ox, oy)
    step = max(geo.slack, 0.0)
    if off <= step:
        return (fx, fy)
    return (cx + ox / off * step, cy + oy / off * step)


class _PathBuilder:
    """GET_DEPLOY_PATH and CALC_TIME of Algorithm 4.1–4.2 for ordered lists of clusters."""

    def __init__(self, inst: _Instance) -> None:
        self.inst = inst
        p = inst.problem
        self.carrier, self.rover = p.carrier, p.rover
        self.unload = p.carrier.deploy_stop_time
        self.start: Point2 = (p.start[0], p.start[1])

    def finish(self, pos: Point2, members: Sequence[int]) -> float:
        """Rover flight time to the cluster's farthest task from ``pos`` (eq. 4.5)."""
        return leg_time(self.inst.reach_from(pos, members), self.rover)

    def place(self, clusters: Sequence[Sequence[int]], geos: Sequence[ClusterGeometry], k: int,
              prev: Point2, t: float, heading: float, worst: float, fine: bool) -> Point2:
        """Deployment point of cluster k given the carrier's state after the previous stop."""
        if k < len(clusters) - 2:
            return max_range_point(prev, geos[k], geos[k + 1].center)
        return self._best_on_segment(prev, t, heading, worst, clusters, geos, k, fine)

    def _best_on_segment(self, prev: Point2, t: float, heading: float, worst: float,
                         clusters: Sequence[Sequence[int]], geos: Sequence[ClusterGeometry], k: int,
                         fine: bool) -> Point2:
        """The last two clusters (eq. 4.14–4.20): slide the stop along prev → centre so that this
        cluster's rovers and the next stop's rovers finish as early as possible, never beyond
        d_deploy. Solved on the exact time model instead of the linearised rotation of eq. 4.16."""
        center = geos[k].center
        s_lo = self.inst.feasible_from(prev, center, clusters[k])
        last = k == len(clusters) - 1
        nxt = None if last else geos[k + 1].center

        def last_stop(pos: Point2, h: float, t1: float, u: float, nxt: Point2) -> float:
            q = _lerp(pos, nxt, u)
            dt2, _ = carrier_hop(pos, q, h, self.carrier)
            return t1 + dt2 + self.unload + self.finish(q, clusters[k + 1])

        def both(s: float, u: float = 1.0) -> tuple[float, float]:
            """This cluster's last arrival and the next (last) cluster's, with the stop at s."""
            pos = _lerp(prev, center, s)
            dt, h = carrier_hop(prev, pos, heading, self.carrier)
            t1 = t + dt + self.unload
            later = last_stop(pos, h, t1, u, nxt) if nxt is not None else 0.0
            return t1 + self.finish(pos, clusters[k]), later

        def makespan(s: float, u: float = 1.0) -> float:
            return max(worst, *both(s, u))

        if not fine and nxt is not None:
            # Eq. 4.20: both clusters' rovers arrive together. This cluster finishes later as the
            # stop moves back toward the carrier, the next one earlier: find the crossing.
            def gap(x: float) -> float:
                a, b = both(x)
                return a - b

            cands = [s_lo, 1.0]
            g_lo, g_hi = gap(s_lo), gap(1.0)
            if g_lo * g_hi < 0:
                cands.append(find_root(gap, s_lo, 1.0, xtol=1e-4))
            return _lerp(prev, center, min(cands, key=makespan))

        def best_s(u: float) -> tuple[float, float]:
            s, best = minimize_1d(lambda x: makespan(x, u), s_lo, 1.0, samples=24 if fine else 6,
                                  tol=1e-7 if fine else 2e-3)
            for cand in (s_lo, 1.0):
                if makespan(cand, u) <= best:
                    s, best = cand, makespan(cand, u)
            return s, best

        s, best = best_s(1.0)
        if fine and nxt is not None:
            # The last stop may stop short of its centre too: place both by coordinate descent on
            # (s, u), u the fraction of the way from this stop to the next centre.
            for _ in range(2):
                pos = _lerp(prev, center, s)
                u_lo = self.inst.feasible_from(pos, nxt, clusters[k + 1])
                def along_u(x: float, s: float = s) -> float:
                    return makespan(s, x)

                u, _ = minimize_1d(along_u, u_lo, 1.0, samples=8, tol=1e-7)
                s2, best2 = best_s(u)
                if best2 >= best - 1e-9:
                    break
                s, best = s2, best2
        return _lerp(prev, center, s)

    def route(self, clusters: list[list[int]], fine: bool = False) -> _Route:
        """GET_DEPLOY_PATH for every cluster, then the route's times."""
        geos = [self.inst.geometry(c) for c in clusters]
        positions: list[Point2] = []
        prev, t, heading, worst = self.start, 0.0, self.inst.problem.heading, 0.0
        for k in range(len(clusters)):
            pos = self.place(clusters, geos, k, prev, t, heading, worst, fine)
            dt, heading = carrier_hop(prev, pos, heading, self.carrier)
            t += dt + self.unload
            worst = max(worst, t + self.finish(pos, clusters[k]))
            positions.append(pos)
            prev = pos
        return _Route(self, clusters, geos, positions)


# a scored change: makespan, clusters, their geometry, stops, first re-placed stop
Candidate = tuple[float, list[list[int]], list[ClusterGeometry], list[Point2], int]


class _Route:
    """An ordered cluster list with its stops and the times needed to re-time a local change.

    ``arrive[j]`` is the carrier's arrival at stop j, ``heading[j]`` its heading on arrival,
    ``done[j]`` when stop j's last rover reaches its task, ``tail[j]`` = max(done[j:]).
    """

    def __init__(self, b: _PathBuilder, clusters: list[list[int]], geos: list[ClusterGeometry],
                 positions: list[Point2], base: _Route | None = None, lo: int = 0) -> None:
        """``base``: a route with the same first ``lo`` stops, whose times are kept."""
        self.b, self.clusters, self.geos, self.positions = b, clusters, geos, positions
        if base is None or lo == 0:
            lo, prev, t, h = 0, b.start, 0.0, b.inst.problem.heading
            self.arrive: list[float] = []
            self.heading: list[float] = []
            self.done: list[float] = []
        else:
            self.arrive, self.heading, self.done = base.arrive[:lo], base.heading[:lo], base.done[:lo]
            prev, t, h = positions[lo - 1], base.arrive[lo - 1] + b.unload, base.heading[lo - 1]
        for members, pos in zip(clusters[lo:], positions[lo:], strict=True):
            dt, h = carrier_hop(prev, pos, h, b.carrier)
            t += dt
            self.arrive.append(t)
            self.heading.append(h)
            t += b.unload
            self.done.append(t + b.finish(pos, members))
            prev = pos
        self.tail = self.done[:]
        for j in range(len(self.tail) - 2, -1, -1):
            self.tail[j] = max(self.tail[j], self.tail[j + 1])
        self.makespan = self.tail[0] if self.tail else 0.0
        self.head = list(itertools.accumulate(self.done, max))  # head[j] = max(done[:j + 1])

    def moved(self, k: int, q: Point2) -> _Route:
        """This route with stop k moved to ``q``: times before k are kept, the rest re-timed."""
        b = self.b
        r = object.__new__(type(self))
        r.b, r.clusters, r.geos = b, self.clusters, self.geos
        r.positions = [*self.positions[:k], q, *self.positions[k + 1:]]
        r.arrive, r.heading, r.done = self.arrive[:k], self.heading[:k], self.done[:k]
        if k == 0:
            prev, t, h = b.start, 0.0, b.inst.problem.heading
        else:
            prev, t, h = self.positions[k - 1], self.arrive[k - 1] + b.unload, self.heading[k - 1]
        for j in range(k, len(self.positions)):
            pos = r.positions[j]
            dt, h = carrier_hop(prev, pos, h, b.carrier)
            t += dt
            r.arrive.append(t)
            r.heading.append(h)
            t += b.unload
            r.done.append(t + b.finish(pos, self.clusters[j]))
            prev = pos
        r.tail = r.done[:]
        for j in range(len(r.tail) - 2, -1, -1):
            r.tail[j] = max(r.tail[j], r.tail[j + 1])
        r.makespan = r.tail[0] if r.tail else 0.0
        r.head = list(itertools.accumulate(r.done, max))
        return r

    def accept(self, cand: Candidate) -> _Route:
        _, clusters, geos, positions, lo = cand
        return _Route(self.b, clusters, geos, positions, self, lo)

    def replace(self, i: int, pieces: list[list[int]], count: int = 1) -> Candidate:
        """Makespan after clusters i..i+count-1 are replaced by ``pieces``, recomputing the stops
        around the change (the one before, the pieces, the one after) and keeping later stops."""
        b, old = self.b, self.clusters
        clusters = old[:i] + pieces + old[i + count:]
        geos = self.geos[:i] + [b.inst.geometry(p) for p in pieces] + self.geos[i + count:]
        lo = max(i - 1, 0)
        hi = i + len(pieces) + 1  # first new index kept from the old route (exclusive window end)
        if hi >= len(clusters) - 2:
            hi = len(clusters)  # the last two clusters are placed together (eq. 4.20)
        if lo == 0:
            prev, t, h, worst = b.start, 0.0, b.inst.problem.heading, 0.0
        else:
            prev = self.positions[lo - 1]
            t, h = self.arrive[lo - 1] + b.unload, self.heading[lo - 1]
            worst = self.head[lo - 1]
        positions = self.positions[:lo]
        for k in range(lo, hi):
            pos = b.place(clusters, geos, k, prev, t, h, worst, fine=False)
            dt, h = carrier_hop(prev, pos, h, b.carrier)
            t += dt + b.unload
            worst = max(worst, t + b.finish(pos, clusters[k]))
            positions.append(pos)
            prev = pos
        m = hi - len(pieces) + count  # old index of the first kept stop
        if m < len(old):
            pos = self.positions[m]
            dt, h = carrier_hop(prev, pos, h, b.carrier)
            t += dt + b.unload
            worst = max(worst, t + b.finish(pos, old[m]))
            if m + 1 < len(old):
                dt, _ = carrier_hop(pos, self.positions[m + 1], h, b.carrier)
                shift = t + dt - self.arrive[m + 1]
                worst = max(worst, self.tail[m + 1] + shift)
            positions += self.positions[m:]
        return worst, clusters, geos, positions, lo


def lee_clusters(problem: DeployProblem, improve: bool = True,
                 t0: float | None = None) -> tuple[list[list[int]], list[Point2], float]:
    """Algorithm 4.1–4.2: divide until every cluster fits d_deploy, then the split/swap/merge loop
    that keeps the fastest path; with ``improve``, then re-sequence and merge clusters and run
    the loop again while that helps. Returns clusters in visiting order, stops and makespan."""
    inst = _Instance(problem)
    builder = _PathBuilder(inst)
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
    def divide(route: _Route, idx: int) -> tuple[list[int], list[int]]:
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

    def finish(r: _Route) -> _Route:
        r = _fresh(builder, r)
        sweeps = 3 if small else 2 if n <= 60 else 1
        return _polish(builder, r, sweeps, 1e-3 if small else COARSE_TOL) if improve else r

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
    if n <= FINE_MOVES_UPTO or stop is not None:  # ... and on the final placement
        best = fine_descent(best, inst.fits_quick, builder.route, finish,
                                stop if n > FINE_MOVES_UPTO else None,
                                slack=0.15 if stop is None else math.inf)
    if stop is not None:  # anytime: iterated local search until the budget
        best = iterated_search(best, inst.fits_quick, builder.route, finish,
                               random.Random(problem.seed), stop, max_fails=ILS_PATIENCE * n)
    return best.clusters, best.positions, best.makespan


def _fresh(builder: _PathBuilder, r: _Route) -> _Route:
    """``r`` or its clusters' stops placed afresh, finely: whichever is faster."""
    fresh = builder.route(r.clusters, fine=True)
    return fresh if fresh.makespan <= r.makespan else r


FINE_MOVES_UPTO = 8  # tasks: up to this many, every move is also scored on fine, polished stops
# (up to n tasks, k): the tasks of a cluster nearest its neighbour that the quick descent offers to it
# (big clusters of big problems: each offer costs an enclosing circle)
QD_KEEP = ((60, 3), (300, 1), (math.inf, 0))
FINE_UPTO = 12  # tasks: up to this many, the polish steps down to 1 mm and today's route is polished too
COARSE_TOL = 5e-2  # m: the polish's last step on larger problems (5 cm of carrier drive: ~3 ms)
ILS_PATIENCE = 20  # kicks per task without a new best before the anytime search gives up


_TAU = 2.0 * math.pi


def _stop_cost(builder: _PathBuilder, r: _Route, k: int) -> Callable[[float, float], float]:
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


def _polish(builder: _PathBuilder, route: _Route, sweeps: int = 3, tol: float = 1e-3) -> _Route:
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


SNAP = 1e-2  # m: a stop closer than this to the previous one is put on it (when its rovers reach)


def build_plan(problem: DeployProblem, planner: str, clusters: Sequence[Sequence[int]],
               positions: Sequence[Point2], compute_ms: float = 0.0) -> Plan:
    """Turn clusters and stops into a timed Plan; rovers leave the deck in order."""
    rover_ids = iter(problem.rover_ids())
    stops: list[Stop] = []
    prev: Vec3 = problem.start
    for members, pos in zip(clusters, positions, strict=True):
        here: Vec3 = (pos[0], pos[1], 0.0)
        reach = problem.deploy_range - RANGE_MARGIN
        if 0.0 < math.dist(prev, here) < SNAP and all(
                math.dist(prev, problem.tasks[i].position) <= reach for i in members):
            # a hop of millimetres has an arbitrary heading once coordinates are rounded for JSON,
            # and turning to it costs real time: stay where the carrier is
            here = prev
        legs = [RoverLeg(rover=next(rover_ids), task=problem.tasks[i].id,
                         path=[here, problem.tasks[i].position]) for i in members]
        stops.append(Stop(position=here, carrier_path=[prev, here], rovers=legs))
        prev = here
    plan = Plan(kind="deploy", planner=planner, start=problem.start, heading=problem.heading, stops=stops,
                compute_ms=compute_ms)
    return retime(plan, problem.carrier, problem.rover)


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
        from planners.deploy.two_task import plan_two_tasks

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
