"""The final placement of a collection route's stops (``planners.collect.lee``'s evaluator): each
stop re-placed once both neighbours are known (dissertation ch. 5.5.1, ``polish``), moved on its own
inside its region on the exact time model (``compass``), and short routes' stops on the smoothed
makespan (``smooth``)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from planners.collect.path import PathBuilder, Route
from planners.collect.reach import INSIDE_TOL, Point2, Region
from planners.core.driver import COARSE_TOL
from planners.core.geometry import compass_search
from planners.core.native import kernels
from planners.core.plan import SNAP
from planners.core.smooth import smooth_compass, smooth_max
from planners.core.timing import Step


def polish(builder: PathBuilder, route: Route,
           place: Callable[[Region, Point2, float, float, Point2 | None, Point2], Point2] | None = None,
           sweeps: int = 2, level: int = 1) -> Route:
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


SNAP2 = SNAP * SNAP


def smooth(builder: PathBuilder, route: Route, tol: float = 1e-3) -> Route:
    """Re-place every stop of a short route on the smoothed eq. 5.2 (``planners.core.smooth``):
    the carrier arriving just as a cluster's last rover lands is a kink the stop-by-stop compass
    search cannot leave (the stop before must move too). Searched from the route's stops, the
    clusters' time centres and each stop nearest the next cluster's; keeps the faster route."""
    if not route.clusters:
        return route
    regions, load, drive, leg = route.regions, builder.load, builder.drive, builder.leg

    inst = builder.inst
    rows = [[(*inst.pts2[i], (inst.rad[i] + INSIDE_TOL) ** 2, inst.h2[i]) for i in c]
            for c in route.clusters]  # (stops on a disc's rim are inside up to rounding)

    def cost(pos: Sequence[Point2], tau: float) -> float:
        prev, h, t = builder.start, builder.heading0, 0.0
        for members, q in zip(rows, pos, strict=True):
            far = 0.0
            for gx, gy, r2, z2 in members:  # outside a reach disc: inf (as the compass search's cost)
                e = (q[0] - gx) ** 2 + (q[1] - gy) ** 2
                if e > r2:
                    return math.inf
                far = max(far, e + z2)
            hop2 = (q[0] - prev[0]) ** 2 + (q[1] - prev[1]) ** 2
            if 0.0 < hop2 < SNAP2:  # the plan would put this stop on the previous one (and lose its turn)
                return math.inf
            dt, h = drive(prev, q, h)
            t = smooth_max(t + dt, leg(math.sqrt(far)), tau) + load
            prev = q
        return t

    def exact(pos: Sequence[Point2]) -> float:
        return cost(pos, 0.0)

    step = max(min(min(builder.inst.rad[i] for i in c) for c in route.clusters) / 4, 0.05)
    centres = [reg.time_center for reg in regions]
    forward = [reg.project(nxt) for reg, nxt in zip(regions, [*centres[1:], centres[-1]], strict=True)]
    starts = [route.positions, centres, forward]  # forward: each stop as near the next cluster as it can
    pos = smooth_compass(cost, exact, starts, step, tol)
    cand = Route(builder, route.clusters, regions, pos)
    return cand if cand.makespan < route.makespan - 1e-9 else route


def _stop_cost(route: Route, k: int) -> Callable[[float, float], float]:
    """Makespan of ``route`` with stop k moved to (x, y), the others kept, or inf outside I_β:
    the hops into k, k + 1 and k + 2 are re-timed, later stops by ``Route.end_from``. The compass
    search calls it thousands of times: the hops are the builder's ``step``
    (``planners.core.timing.carrier_stepper``)."""
    b = route.b
    inst, step, leg, load = b.inst, b.step, b.leg, b.load
    members = route.clusters[k]
    rows = [(inst.pts2[i][0], inst.pts2[i][1], inst.rad[i] ** 2, inst.h2[i])
            for i in members]
    (px, py), t0, h0 = route.state_before(k)
    n = len(route.positions)
    # the next two stops and when their rovers are ready (kept), then ``Route.end_from`` written out
    later = [(q[0], q[1], rd) for q, rd in zip(route.positions[k + 1:k + 3], route.ready[k + 1:k + 3],
                                               strict=True)]
    last = k + len(later)
    tail = (route.after[last], route.late[last]) if k + 1 < n else None
    # the compiled twin when it is built: the same floats
    make = collect_stop_cost if kernels is None else kernels.CollectStopCost
    return make(rows, step, leg, (px, py, h0, t0), load, later, tail)


def collect_stop_cost(rows: Sequence[tuple[float, float, float, float]], step: Step,
                      leg: Callable[[float], float],
                      start: tuple[float, float, float, float], load: float,
                      later: Sequence[tuple[float, float, float]],
                      tail: tuple[float, float] | None) -> Callable[[float, float], float]:
    """``_stop_cost``'s cost(x, y) from its fixed data: the rovers' (x, y, ρ², z²), the carrier's
    step and the rovers' leg, the start (x, y, heading, time), the load time, the next stops
    (x, y, ready) re-timed, and ``Route.end_from``'s (after, late) of the last of them (None when
    stop k is the last)."""
    px, py, h0, t0 = start
    after, late = tail if tail is not None else (0.0, 0.0)
    sqrt, inf = math.sqrt, math.inf

    def cost(x: float, y: float) -> float:
        far = 0.0
        for gx, gy, r2, z2 in rows:
            e = (x - gx) ** 2 + (y - gy) ** 2
            if e > r2:
                return inf
            if e + z2 > far:
                far = e + z2
        dt, h = step(x - px, y - py, h0)
        t, ready = t0 + dt, leg(sqrt(far))
        t = (ready if ready > t else t) + load  # (max(t0 + dt, ready) + load, written out)
        qx, qy = x, y
        for nx, ny, rd in later:
            dt, h = step(nx - qx, ny - qy, h)
            t += dt  # (max(t + dt, rd), written out)
            if rd > t:
                t = rd
            t += load
            qx, qy = nx, ny
        if tail is not None:  # Route.end_from(last, t)
            t += after
            return late if late > t else t
        return t

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
            step = max(min(inst.rad[i] for i in route.clusters[k]) / 4, 0.05)
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
