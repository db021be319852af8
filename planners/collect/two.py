"""Optimal collection of two rovers (dissertation ch. 5.3, eq. 5.4–5.11), in 2D and 3D.

Two ways to collect two rovers (Fig. 5.5): together at one point of their common region, or one
after the other. One after the other, the carrier should meet the first rover RV1 where both arrive
at once: without acceleration and rotation on the circle of Apollonius O_A1 between the carrier's
start and RV1 (ratio v_c/v_r). Of that circle the point nearest the line from the carrier to the
other rover is taken, clamped to RV1's reach disc (the chapter's three steps). The carrier's
rotation and acceleration (eq. 5.4–5.10) and RV1's height (eq. 5.11) then move the point; instead of
the linearised Δθ of eq. 5.10 we minimise the exact makespan of eq. 5.2 from that start, the second
stop placed optimally for each first stop. The fastest way wins.
"""

from __future__ import annotations

import math

from planners.collect.path import PathBuilder, Route
from planners.collect.polish import polish
from planners.collect.reach import Point2, Region
from planners.core.timing import carrier_hop
from planners.deploy.two_task import apollonius_circle


def apollonius_guess(start: Point2, first: Point2, other: Point2, v_c: float, v_r: float) -> Point2 | None:
    """Point of O_A1 (carrier from ``start`` and rover from ``first`` arrive together) nearest the
    line start → other, or None when the carrier is not faster than the rover."""
    if v_c <= v_r:
        return None
    (cx, cy), rad = apollonius_circle(first, start, v_c, v_r)
    dx, dy = other[0] - start[0], other[1] - start[1]
    n = math.hypot(dx, dy)
    if n < 1e-12:
        return None
    ux, uy = dx / n, dy / n
    s = (cx - start[0]) * ux + (cy - start[1]) * uy
    fx, fy = start[0] + s * ux, start[1] + s * uy  # foot of the centre on the line
    off = math.hypot(fx - cx, fy - cy)
    if off <= rad:  # the line crosses O_A1: its crossing nearer the carrier
        back = math.sqrt(rad * rad - off * off)
        t = max(s - back, 0.0) if s - back >= 0 else s + back
        return (start[0] + t * ux, start[1] + t * uy)
    return (cx + (fx - cx) / off * rad, cy + (fy - cy) / off * rad)  # the circle's point nearest the line


def two_rover_route(builder: PathBuilder) -> Route:
    """The best of: both rovers at one stop; RV1 then RV2; RV2 then RV1 (ch. 5.3)."""
    from scipy.optimize import minimize  # SciPy on demand: only two-rover collections need it

    inst = builder.inst
    c, r = builder.carrier, builder.rover
    routes: list[Route] = []
    if inst.fits([0, 1]):
        routes.append(polish(builder, builder.route([[0, 1]], level=2), level=2))
    for a, b in ((0, 1), (1, 0)):
        disc_a = inst.region([a])
        region_b = inst.region([b])

        def makespan_at(p: Point2, a: int = a, b: int = b, disc_a: Region = disc_a,
                        region_b: Region = region_b) -> tuple[float, Route]:
            q = disc_a.project(p)
            dt, h = carrier_hop(builder.start, q, builder.heading0, c)
            t = max(dt, builder.ready(disc_a, q)) + builder.load
            second = builder.place(region_b, q, t, h, None, level=2)
            route = Route(builder, [[a], [b]], [disc_a, region_b], [q, second])
            return route.makespan, route

        guesses: list[Point2] = [inst.pts2[a], disc_a.project(builder.start)]
        g = apollonius_guess(builder.start, inst.pts2[a], inst.pts2[b], c.max_speed, r.max_speed)
        if g is not None:
            guesses.append(disc_a.project(g))
        best_v, best_route = min((makespan_at(p) for p in guesses), key=lambda x: x[0])
        x0 = best_route.positions[0]
        scale = max(float(inst.radii[a]), 1.0)
        res = minimize(lambda x: makespan_at((float(x[0]), float(x[1])))[0], x0, method="Nelder-Mead",
                       options={"xatol": 1e-7, "fatol": 1e-9, "maxiter": 400,
                                "initial_simplex": [x0, (x0[0] + 0.2 * scale, x0[1]),
                                                    (x0[0], x0[1] + 0.2 * scale)]})
        v, route = makespan_at((float(res.x[0]), float(res.x[1])))
        routes.append(route if v < best_v else best_route)
    return min(routes, key=lambda rt: rt.makespan)

