"""Open-space collection (dissertation ch. 5): clusters of rovers meet the carrier at one stop each.

Vocabulary follows the chapter: rovers are grouped into clusters P_γβ whose reach discs share a
region I_β (eq. 5.12, ``planners.collect.reach``); the carrier stops once per cluster at a collection
location q_γβ in I_β; every rover starts flying to its meeting point at t = 0 and the carrier waits
for the cluster's last rover, then loads (eq. 5.2). The makespan is the last stop's departure.

Algorithm 5.1 divides the rovers until every cluster has a common region; Algorithm 5.2 then
tries to divide each cluster, in both orders (SWAP_CLUSTERS), keeps the division when the path
gets faster and merges it back otherwise. GET_COLLECT_PATH places every cluster's stop in turn
(``_PathBuilder.place``): the fast way scores the chapter's candidate points (the circles'
intersection points and the points of I_β nearest the carrier's line, eq. 5.13–5.16) on the time
model; ``planners.collect.convex`` solves the same placement as a constrained program.
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Callable, Sequence

import numpy as np

from planners.collect.reach import Point2, Region, make_region
from planners.core.clustering import divide_cluster
from planners.core.geometry import compass_search, minimize_1d
from planners.core.moves import (
    deadline,
    fine_descent,
    iterated_search,
    merge,
    quick_descent,
    relocate_nearest,
    swap,
)
from planners.core.plan import Plan, RoverLeg, Stop
from planners.core.problem import CollectProblem, PlanningError, Vec3, refuse_obstacles
from planners.core.search import merge_neighbours, reorder, split_loop
from planners.core.timing import RANGE_MARGIN, carrier_hop, carrier_step, leg_time, retime


class CollectInstance:
    """Per-problem caches: rover ground positions, reach radii and cluster regions by membership."""

    def __init__(self, problem: CollectProblem) -> None:
        check_rovers(problem)
        self.problem = problem
        rovers = problem.rovers
        self.ground = np.array([[r.position[0], r.position[1]] for r in rovers], dtype=float).reshape(-1, 2)
        z = np.array([r.position[2] for r in rovers], dtype=float)
        self.heights2 = z * z
        rng = np.array([r.range for r in rovers], dtype=float)
        # Reach radius on the ground, kept RANGE_MARGIN inside the range (timing.RANGE_MARGIN).
        self.radii = np.sqrt(np.maximum(np.maximum(rng - RANGE_MARGIN, 0.0) ** 2 - self.heights2, 0.0))
        self.pts2: list[Point2] = [(float(x), float(y)) for x, y in self.ground.tolist()]
        self._regions: dict[tuple[int, ...], Region] = {}

    def region(self, members: Sequence[int]) -> Region:
        key = tuple(sorted(members))
        reg = self._regions.get(key)
        if reg is None:
            reg = make_region(key, self.ground, self.radii, self.heights2)
            self._regions[key] = reg
        return reg

    def fits(self, members: Sequence[int]) -> bool:
        """GET_INTERPTS of Algorithm 5.1 is non-empty: the cluster's reach discs intersect."""
        key = tuple(sorted(members))
        reg = self._regions.get(key)
        if reg is not None:
            return reg.feasible
        if len(members) > 1:  # cheap necessary test: the last rover's disc meets every other disc
            last = members[-1]
            idx = np.asarray(members[:-1])
            gap = np.hypot(*(self.ground[idx] - self.ground[last]).T) - self.radii[idx] - self.radii[last]
            if gap.max() > 1e-9:
                return False
        return self.region(key).feasible


def check_rovers(problem: CollectProblem) -> None:
    """Reject rovers no plan can collect, by id: a rover must at least be able to land below itself."""
    seen: set[str] = set()
    for r in problem.rovers:
        if r.id in seen:
            raise PlanningError(f"rover {r.id} is listed twice in the collection; give each rover once")
        seen.add(r.id)
        z = r.position[2]
        if z < 0:
            raise PlanningError(f"rover {r.id} is below the ground (z = {z:g} m); heights are above ground")
        if not r.range >= z:
            raise PlanningError(
                f"rover {r.id} cannot be collected: it hovers {z:g} m up with only {r.range:g} m of range "
                f"left, so it cannot even land below itself; it needs a range of at least {z:g} m")


class _PathBuilder:
    """GET_COLLECT_PATH and CALC_TIME of Algorithm 5.1–5.2 for ordered lists of clusters."""

    def __init__(self, inst: CollectInstance) -> None:
        self.inst = inst
        p = inst.problem
        self.carrier, self.rover = p.carrier, p.rover
        self.load = p.carrier.collect_stop_time
        self.start: Point2 = (p.start[0], p.start[1])
        self.heading0 = p.heading

    def ready(self, region: Region, p: Point2) -> float:
        """g(q_γ) of eq. 5.2: when the cluster's last rover lands at ``p`` (all leave at t = 0)."""
        return leg_time(region.farthest_flight(p), self.rover)

    def local_time(self, region: Region, p: Point2, prev: Point2, t: float, heading: float,
                   nxt: Point2 | None) -> float:
        """η_β of eq. 5.2 at ``p`` plus the hop on to the next stop: what placing q_γβ at p costs."""
        dt, h = carrier_hop(prev, p, heading, self.carrier)
        eta = max(t + dt, self.ready(region, p)) + self.load
        if nxt is not None:
            eta += carrier_hop(p, nxt, h, self.carrier)[0]
        return eta

    def place(self, region: Region, prev: Point2, t: float, heading: float, nxt: Point2 | None,
              level: int = 0) -> Point2:
        """Collection location of one cluster given the carrier's state after the previous stop.

        Level 0 (the clustering search) scores a few points: the time centre, the point nearest
        the previous stop and the carrier's line point (eq. 5.13). Levels 1–2 score the chapter's
        full candidate set (Fig. 5.6: the circles' intersection points, eq. 5.13–5.16) and slide the
        best toward the time centre and the line point (level 2: toward every candidate); I_β is
        convex, so every such segment stays inside it.
        """
        def cost(p: Point2) -> float:
            return self.local_time(region, p, prev, t, heading, nxt)

        if level == 0:
            return min(region.quick_candidates(prev, nxt), key=cost)
        cands = region.candidates(prev, nxt)
        vals = [cost(p) for p in cands]
        j = min(range(len(cands)), key=vals.__getitem__)
        best, best_v = cands[j], vals[j]
        targets = cands if level >= 2 else [region.time_center, region.line_point(prev, nxt)]
        for q in targets:
            if math.dist(q, best) < 1e-6:
                continue
            a = best

            def along(s: float, a: Point2 = a, q: Point2 = q) -> float:
                return cost((a[0] + s * (q[0] - a[0]), a[1] + s * (q[1] - a[1])))

            s, v = minimize_1d(along, 0.0, 1.0, samples=8 if level >= 2 else 4,
                               tol=1e-7 if level >= 2 else 1e-4)
            if v < best_v:
                best, best_v = (a[0] + s * (q[0] - a[0]), a[1] + s * (q[1] - a[1])), v
        return best

    def route(self, clusters: list[list[int]], level: int = 0) -> _Route:
        """GET_COLLECT_PATH for every cluster in order, then the route's times (CALC_TIME)."""
        regions = [self.inst.region(c) for c in clusters]
        positions: list[Point2] = []
        prev, t, heading = self.start, 0.0, self.heading0
        for k, reg in enumerate(regions):
            nxt = regions[k + 1].center if k + 1 < len(regions) else None  # next stop not known yet
            pos = self.place(reg, prev, t, heading, nxt, level)
            dt, heading = carrier_hop(prev, pos, heading, self.carrier)
            t = max(t + dt, self.ready(reg, pos)) + self.load
            positions.append(pos)
            prev = pos
        return _Route(self, clusters, regions, positions)


# a scored change: makespan, clusters, stops, first re-placed stop, end of the re-placed stops,
# the old index of the first kept stop
Candidate = tuple[float, list[list[int]], list[Point2], int, int, int]


class _Route:
    """An ordered cluster list with its stops and the times eq. 5.2 gives them.

    ``hop[j]`` is the carrier's rotation + drive into stop j, ``heading[j]`` its heading on arrival,
    ``ready[j]`` when stop j's last rover lands, ``eta[j]`` the departure from stop j.
    """

    def __init__(self, b: _PathBuilder, clusters: list[list[int]], regions: list[Region],
                 positions: list[Point2]) -> None:
        self.b, self.clusters, self.regions, self.positions = b, clusters, regions, positions
        self.hop: list[float] = []
        self.heading: list[float] = []
        self.ready: list[float] = []
        prev, h = b.start, b.heading0
        for reg, pos in zip(regions, positions, strict=True):
            dt, h = carrier_hop(prev, pos, h, b.carrier)
            self.hop.append(dt)
            self.heading.append(h)
            self.ready.append(b.ready(reg, pos))
            prev = pos
        self._times()

    def _times(self) -> None:
        """``eta`` and the makespan from ``hop`` and ``ready`` (eq. 5.2), and the suffix sums.

        Eq. 5.2 is max-plus linear in a departure time: leaving stop j at t, the route ends at
        max(t + after[j], late[j]) (after: hops and loads still to come; late: the latest a later
        cluster's rovers hold the carrier up), so re-timing a local change costs O(1)."""
        load, n = self.b.load, len(self.hop)
        self.eta = []
        t = 0.0
        for dt, ready in zip(self.hop, self.ready, strict=True):
            t = max(t + dt, ready) + load
            self.eta.append(t)
        self.makespan = t if n else 0.0
        self.after = [0.0] * n
        self.late = [-math.inf] * n
        for j in range(n - 2, -1, -1):
            self.after[j] = self.after[j + 1] + self.hop[j + 1] + load
            self.late[j] = max(self.late[j + 1], self.ready[j + 1] + load + self.after[j + 1])

    def moved(self, k: int, q: Point2) -> _Route:
        """This route with stop k moved to ``q``: only the hops whose turn or length changed (into
        k, k + 1, k + 2 and on while the arrival heading differs) are driven again."""
        b = self.b
        r = object.__new__(type(self))
        r.b, r.clusters, r.regions = b, self.clusters, self.regions
        r.positions = [*self.positions[:k], q, *self.positions[k + 1:]]
        r.hop, r.heading, r.ready = self.hop[:], self.heading[:], self.ready[:]
        r.ready[k] = b.ready(self.regions[k], q)
        prev, h = (b.start, b.heading0) if k == 0 else (self.positions[k - 1], self.heading[k - 1])
        for j in range(k, len(r.positions)):
            if j > k + 1 and h == self.heading[j - 1]:
                break
            r.hop[j], h = carrier_hop(prev, r.positions[j], h, b.carrier)
            r.heading[j] = h
            prev = r.positions[j]
        r._times()
        return r

    def end_from(self, j: int, t: float) -> float:
        """Makespan when the carrier leaves stop j at ``t`` and later stops keep their places."""
        return max(t + self.after[j], self.late[j])

    def state_before(self, k: int) -> tuple[Point2, float, float]:
        """Carrier position, time and heading when it leaves the stop before stop k."""
        if k == 0:
            return self.b.start, 0.0, self.b.heading0
        return self.positions[k - 1], self.eta[k - 1], self.heading[k - 1]

    def _finish(self, m: int, prev: Point2, t: float, h: float) -> float:
        """Makespan when the carrier leaves ``prev`` at ``t`` with heading ``h`` for old stop m."""
        b = self.b
        last = min(m + 2, len(self.positions))
        for j in range(m, last):  # the heading into m changed, so the rotation at m (into m + 1) too
            pos = self.positions[j]
            dt, h = carrier_hop(prev, pos, h, b.carrier)
            t = max(t + dt, self.ready[j]) + b.load
            prev = pos
        return self.end_from(last - 1, t)

    def accept(self, cand: Candidate) -> _Route:
        """The route of a scored change: stops before ``lo`` and from old stop ``m`` on keep their
        hops and rovers' times; only the changed stops (and the hops whose heading changed) are
        driven again, so a long route accepts a local change in a few hops."""
        _, clusters, positions, lo, hi, m = cand
        b = self.b
        r = object.__new__(type(self))
        r.b, r.clusters, r.positions = b, clusters, positions
        r.regions = [*self.regions[:lo], *(b.inst.region(c) for c in clusters[lo:hi]), *self.regions[m:]]
        r.hop, r.heading, r.ready = self.hop[:lo], self.heading[:lo], self.ready[:lo]
        prev, h = (b.start, b.heading0) if lo == 0 else (positions[lo - 1], self.heading[lo - 1])
        for j in range(lo, len(positions)):
            o = j - hi + m  # the old index of a kept stop
            if j > hi and h == self.heading[o - 1]:  # the rest is driven as before
                r.hop += self.hop[o:]
                r.heading += self.heading[o:]
                r.ready += self.ready[o:]
                break
            dt, h = carrier_hop(prev, positions[j], h, b.carrier)
            r.hop.append(dt)
            r.heading.append(h)
            r.ready.append(b.ready(r.regions[j], positions[j]) if j < hi else self.ready[o])
            prev = positions[j]
        r._times()
        return r

    def replace(self, i: int, pieces: list[list[int]], count: int = 1) -> Candidate:
        """Makespan after clusters i..i+count-1 are replaced by ``pieces``: the stop before, the
        pieces and their stops are placed afresh; later stops keep their places and are re-timed."""
        b, old = self.b, self.clusters
        clusters = old[:i] + pieces + old[i + count:]
        regions = self.regions[:i] + [b.inst.region(p) for p in pieces] + self.regions[i + count:]
        lo = max(i - 1, 0)
        hi = min(i + len(pieces), len(clusters))  # new indices lo..hi-1 are placed afresh
        m = hi - len(pieces) + count  # old index of the first kept stop
        prev, t, h = self.state_before(lo)
        positions = self.positions[:lo]
        for k in range(lo, hi):
            if k + 1 < hi:
                nxt: Point2 | None = regions[k + 1].center
            else:
                nxt = self.positions[m] if m < len(old) else None
            pos = b.place(regions[k], prev, t, h, nxt)
            dt, h = carrier_hop(prev, pos, h, b.carrier)
            t = max(t + dt, b.ready(regions[k], pos)) + b.load
            positions.append(pos)
            prev = pos
        if m < len(old):
            t = self._finish(m, prev, t, h)
            positions = positions + self.positions[m:]
        return t, clusters, positions, lo, hi, m


def _move_rovers(builder: _PathBuilder, route: _Route) -> _Route:
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


def polish(builder: _PathBuilder, route: _Route,
           place: Callable[[Region, Point2, float, float, Point2 | None, Point2], Point2] | None = None,
           sweeps: int = 2, level: int = 1) -> _Route:
    """Re-place every stop now that both neighbours are known (the improvement ch. 5.5.1 suggests
    for Fig. 5.9d: q_γ5 moved onto the segment q_γ4 q_γ6); keep a move only if the makespan drops."""
    if place is None:
        def place(reg: Region, prev: Point2, t: float, h: float, nxt: Point2 | None, now: Point2) -> Point2:
            return builder.place(reg, prev, t, h, nxt, level)
    for _ in range(sweeps):
        improved = False
        for k in range(len(route.clusters)):
            prev, t, h = route.state_before(k)
            nxt = route.positions[k + 1] if k + 1 < len(route.positions) else None
            pos = place(route.regions[k], prev, t, h, nxt, route.positions[k])
            if math.dist(pos, route.positions[k]) < 1e-9:
                continue
            cand = route.moved(k, pos)
            if cand.makespan < route.makespan - 1e-9:
                route, improved = cand, True
        if not improved:
            break
    return route


def _stop_cost(route: _Route, k: int) -> Callable[[float, float], float]:
    """Makespan of ``route`` with stop k moved to (x, y), the others kept, or inf outside I_β:
    the hops into k, k + 1 and k + 2 are re-timed, later stops by ``_Route.end_from``. The compass
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


def compass(builder: _PathBuilder, route: _Route, sweeps: int = 2, tol: float = 1e-3) -> _Route:
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


def _initial_clusters(builder: _PathBuilder) -> list[list[int]]:
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
              t0: float | None = None) -> tuple[_PathBuilder, _Route]:
    """Algorithm 5.1–5.2, then (with ``improve``) re-sequencing, merging and handing rovers over
    while that helps, and a final fine placement of every stop with both neighbours known."""
    inst = CollectInstance(problem)
    builder = _PathBuilder(inst)
    if not problem.rovers:
        return builder, _Route(builder, [], [], [])

    def divide(route: _Route, idx: int) -> tuple[list[int], list[int]]:
        prev = builder.start if idx == 0 else route.positions[idx - 1]
        return divide_cluster(route.clusters[idx], inst.pts2, prev)  # Algorithm 3.1

    rejected: set[tuple] = set()
    route = split_loop(builder.route(_initial_clusters(builder)), divide, rejected, accept_ties=False)
    for _ in range(3 if improve else 0):  # improvement search beyond the dissertation
        better = reorder(route, route.positions, builder.start, builder.route)
        better = merge_neighbours(better, inst.fits)
        if len(problem.rovers) <= MOVE_ROVERS_UPTO:  # (larger: the quick descent's bounded relocate)
            better = _move_rovers(builder, better)
        better = split_loop(better, divide, rejected, accept_ties=False)
        if better.makespan >= route.makespan - 1e-9:
            break
        route = better
    small = len(problem.rovers) <= fine_upto

    def finish(r: _Route) -> _Route:
        if small:  # place every stop afresh, finely, and keep the faster
            fresh = builder.route(r.clusters, 2)
            r = fresh if fresh.makespan <= r.makespan else r
        r = polish(builder, r, sweeps=2 if small else 1, level=2 if small else 1)
        return compass(builder, r, tol=1e-3 if small else COARSE_TOL)

    stop = deadline(problem.budget_ms, t0) if improve else None
    if not improve:
        best = finish(route)
    else:  # group and order moves (planners.core.moves), scored on the quick placement ...
        keep = next(k for upto, k in QD_KEEP if len(problem.rovers) <= upto)

        def nearness(rover: int, cluster: Sequence[int]) -> float:
            c, p = inst.region(cluster).center, inst.pts2[rover]
            return (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2

        moved = quick_descent(route, inst.fits, cheap=(swap, relocate_nearest(nearness, keep), merge))
        best = finish(moved)
        if small and moved is not route:  # (large routes: the moves' route alone is placed finely)
            today = finish(route)
            best = today if today.makespan < best.makespan else best
        if len(problem.rovers) <= FINE_MOVES_UPTO or stop is not None:  # ... and on the final stops
            best = fine_descent(best, inst.fits, builder.route, finish,
                                stop if len(problem.rovers) > FINE_MOVES_UPTO else None,
                                slack=0.15 if stop is None else math.inf)
    if stop is not None:  # anytime: iterated local search until the budget
        best = iterated_search(best, inst.fits, builder.route, finish, random.Random(problem.seed), stop,
                               max_fails=ILS_PATIENCE * len(problem.rovers))
    route = best
    if len(problem.rovers) == 2:
        from planners.collect.two import two_rover_route  # the ch. 5.3 optimum, where it applies

        two = two_rover_route(builder)
        if two.makespan < route.makespan:
            route = compass(builder, two)
    return builder, route


FINE_MOVES_UPTO = 8  # rovers: up to this many, every move is also scored on fine, polished stops
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
    if 0.0 < math.dist(prev[:2], here[:2]) < 1e-2:
        snapped: Vec3 = (prev[0], prev[1], 0.0)
        if all(math.dist(problem.rovers[i].position, snapped) <= problem.rovers[i].range - 1e-5
               for i in members):
            return snapped
    return here


def plan_collect_lee(problem: CollectProblem) -> Plan:
    """The dissertation's collection path generator (ch. 5.4) with the fast meeting points; ``lee``."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "lee")
    _, route = lee_route(problem, t0=t0)
    ms = (time.perf_counter() - t0) * 1e3
    return build_collect_plan(problem, "lee", route.clusters, route.positions, ms)

