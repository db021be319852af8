"""Re-placing a collection route's stops once both neighbours are known (dissertation ch. 5.5.1),
and on the smoothed makespan for short routes."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from planners.collect.path import PathBuilder, Route
from planners.collect.reach import INSIDE_TOL, Point2, Region
from planners.core.plan import SNAP
from planners.core.smooth import smooth_compass, smooth_max
from planners.core.timing import carrier_hop, leg_time


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
    regions, load, carrier = route.regions, builder.load, builder.carrier

    inst = builder.inst
    rows = [[(*inst.pts2[i], (float(inst.radii[i]) + INSIDE_TOL) ** 2, float(inst.heights2[i])) for i in c]
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
            dt, h = carrier_hop(prev, q, h, carrier)
            t = smooth_max(t + dt, leg_time(math.sqrt(far), builder.rover), tau) + load
            prev = q
        return t

    def exact(pos: Sequence[Point2]) -> float:
        return cost(pos, 0.0)

    step = max(min(float(min(builder.inst.radii[i] for i in c)) for c in route.clusters) / 4, 0.05)
    centres = [reg.time_center for reg in regions]
    forward = [reg.project(nxt) for reg, nxt in zip(regions, [*centres[1:], centres[-1]], strict=True)]
    starts = [route.positions, centres, forward]  # forward: each stop as near the next cluster as it can
    pos = smooth_compass(cost, exact, starts, step, tol)
    cand = Route(builder, route.clusters, regions, pos)
    return cand if cand.makespan < route.makespan - 1e-9 else route

