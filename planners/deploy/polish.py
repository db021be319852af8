"""The final placement of a deployment route's stops (``planners.deploy.lee``'s evaluator): each stop
afresh and finely, each stop moved on its own on the exact time model (``polish``; long routes with
numpy, ``planners.deploy.stops``), and short routes' stops on the smoothed makespan (``smooth``,
``planners.core.smooth``)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from planners.core.driver import COARSE_TOL
from planners.core.geometry import compass_search
from planners.core.plan import SNAP
from planners.core.problem import Point2
from planners.core.smooth import smooth_compass, smooth_max
from planners.core.timing import carrier_hop, leg_time
from planners.deploy.cluster import max_range_point
from planners.deploy.path import PathBuilder, Route
from planners.deploy.stops import search_class, stop_cost

SNAP2 = SNAP * SNAP


def smooth(builder: PathBuilder, route: Route, tol: float = 1e-3) -> Route:
    """Every stop of ``route`` re-placed on the smoothed makespan (the latest last arrival): where
    two stops' rovers arrive last together, one stop moving alone cannot help. Searched from the
    route's stops, the clusters' centres and ``_forward``; keeps the faster route."""
    if not route.clusters:
        return route
    inst, unload, carrier = builder.inst, builder.unload, builder.carrier
    clusters, d = route.clusters, inst.d

    rows = [[(inst.pts[i][0], inst.pts[i][1], inst.pts[i][2] ** 2) for i in c] for c in clusters]
    d2 = (d + 1e-9) ** 2  # (a stop at the range's rim is inside up to rounding)

    def cost(pos: Sequence[Point2], tau: float) -> float:
        prev, h, t, worst = builder.start, inst.problem.heading, 0.0, -math.inf
        for members, q in zip(rows, pos, strict=True):
            far = 0.0
            for tx, ty, z2 in members:
                far = max(far, (tx - q[0]) ** 2 + (ty - q[1]) ** 2 + z2)
            if far > d2:  # a task out of reach (as the polish's cost)
                return math.inf
            hop2 = (q[0] - prev[0]) ** 2 + (q[1] - prev[1]) ** 2
            if 0.0 < hop2 < SNAP2:  # the plan would put this stop on the previous one (and lose its turn)
                return math.inf
            dt, h = carrier_hop(prev, q, h, carrier)
            t += dt + unload
            worst = smooth_max(worst, t + leg_time(math.sqrt(far), builder.rover), tau)
            prev = q
        return worst

    def exact(pos: Sequence[Point2]) -> float:
        return cost(pos, 0.0)

    centres = [g.center for g in route.geos]
    starts = [route.positions, centres, _forward(route)]
    pos = smooth_compass(cost, exact, starts, max(d / 4, 0.05), tol)
    cand = Route(builder, clusters, route.geos, pos)
    return cand if cand.makespan < route.makespan - 1e-9 else route


def _forward(route: Route) -> list[Point2]:
    """Every stop as far toward the next cluster's centre as its rovers' range allows (the last at
    its centre): a start in the other basin from the chapter's stops, which lean toward the
    previous stop."""
    out: list[Point2] = []
    geos = route.geos
    for k, g in enumerate(geos):
        if k + 1 == len(geos):
            out.append(g.center)
            continue
        (cx, cy), (tx, ty) = g.center, geos[k + 1].center
        off = math.hypot(tx - cx, ty - cy)
        s = min(g.slack, off) / off if off > 0 else 0.0
        out.append((cx + s * (tx - cx), cy + s * (ty - cy)))
    return out


def place_finely(builder: PathBuilder, r: Route, small: bool, improve: bool = True) -> Route:
    """The final placement of a route's stops: afresh and finely if faster (``fresh``), then (with
    ``improve``) every stop polished: small routes down to 1 mm in three sweeps, long ones in one
    sweep (with numpy from ``BATCH_STOPS`` stops on)."""
    r = fresh(builder, r)
    if not improve:
        return r
    if len(builder.inst.pts) >= BATCH_FROM:  # one sweep: long routes with numpy, short ones stop by stop
        return polish_long(builder, r, COARSE_TOL) if len(r.clusters) >= BATCH_STOPS else (
            polish(builder, r, 1, COARSE_TOL))
    return polish(builder, r, 3 if small else 2, 1e-3 if small else COARSE_TOL)


def fresh(builder: PathBuilder, r: Route) -> Route:
    """``r`` or its clusters' stops placed afresh, finely: whichever is faster."""
    fresh = builder.route(r.clusters, fine=True)
    return fresh if fresh.makespan <= r.makespan else r



def polish(builder: PathBuilder, route: Route, sweeps: int = 3, tol: float = 1e-3) -> Route:
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
            route = polish_stop(builder, route, k, tol)
            if route.positions[k] != was:
                moved.add(k)
        if route.makespan >= before - 1e-6:
            break
        todo = {j for k in moved for j in range(k - 2, k + 3) if 0 <= j < len(route.clusters)}
    return route


def polish_stop(builder: PathBuilder, route: Route, k: int, tol: float) -> Route:
    """``route`` with stop k searched (``polish``), every other stop fixed."""
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


def polish_long(builder: PathBuilder, route: Route, tol: float) -> Route:
    """One sweep of ``polish`` for long routes, with numpy: every third stop at once
    (stops three apart share no hop), the three classes in turn, each
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
        route = polish_stop(builder, route, k, tol)
    return route


BATCH_STRIDE = 3  # stops: moving stop k changes the hops k, k + 1 and the turn at k + 1
BATCH_FROM = 61  # tasks: from this many on, the final polish sweeps once ...
BATCH_STOPS = 40  # ... and a route of this many stops has a class of stops searched at once
