"""Collection with the meeting points solved as constrained programs (ch. 5.4, eq. 5.13/5.16);
planner ``lee-convex``.

The chapter finds the collection location q_γβ of a cluster as the point of its common region I_β
(the intersection of the rovers' reach discs) nearest the carrier's line, by a convex solver, and
calls the circles' intersection points the cheap alternative (Fig. 5.6). Here the same constraint
set ‖q − g_j‖² ≤ ρ_j² (eq. 5.13/5.16's constraints) carries the time objective directly, in
epigraph form over (x, y, w):

    minimise   w + f(q, q_next)                        (carrier on to the next stop, eq. 4.2)
    subject to w ≥ η_{β−1} + f(q_{β−1}, q)              (carrier arrival, eq. 5.2)
               w ≥ leg_r(√(‖q − g_j‖² + z_j²))          (each rover's landing, eq. 5.2's g)
               ρ_j² − ‖q − g_j‖² ≥ 0                    (reach disc of every rover j in P_γβ)

solved by SLSQP from the fast planner's point, stop by stop with both neighbours known, sweeping
the route until no stop moves; a move is kept only if the makespan of eq. 5.2 drops. The cluster
search (Algorithm 5.1–5.2) compares routes placed the fast way: solving a program inside every
comparison is what made the dissertation's convex variant take 193.6 s at 100 rovers.
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
from scipy.optimize import minimize

from planners.collect.build import build_collect_plan
from planners.collect.lee import lee_route
from planners.collect.path import PathBuilder, Route
from planners.collect.polish import polish
from planners.collect.reach import Point2, Region
from planners.core.plan import Plan
from planners.core.problem import CollectProblem, refuse_obstacles
from planners.core.timing import carrier_hop, leg_time


def convex_place(builder: PathBuilder, region: Region, prev: Point2, t: float, heading: float,
                 nxt: Point2 | None, start: Point2) -> Point2:
    """Solve the epigraph program above for one stop, starting from ``start`` (a point of I_β)."""
    c, r = builder.carrier, builder.rover
    g = region.centers
    z2 = region.heights2
    rho2 = region.radii ** 2

    def arrive(q: np.ndarray) -> tuple[float, float]:
        return carrier_hop(prev, (q[0], q[1]), heading, c)

    def objective(v: np.ndarray) -> float:
        if nxt is None:
            return float(v[2])
        _, h = arrive(v)
        return float(v[2]) + carrier_hop((v[0], v[1]), nxt, h, c)[0]

    def constraints(v: np.ndarray) -> np.ndarray:
        d2 = (v[0] - g[:, 0]) ** 2 + (v[1] - g[:, 1]) ** 2
        flights = np.array([leg_time(math.sqrt(x), r) for x in (d2 + z2).tolist()])
        return np.concatenate([[v[2] - t - arrive(v)[0]], v[2] - flights, rho2 - d2])

    w0 = max(t + arrive(np.array(start))[0], builder.ready(region, start))
    x0 = np.array([start[0], start[1], w0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = minimize(objective, x0, method="SLSQP", constraints=[{"type": "ineq", "fun": constraints}],
                       options={"maxiter": 60, "ftol": 1e-9})
    q = (float(res.x[0]), float(res.x[1]))
    return q if region.contains(q) else region.project(q)


def lee_convex_route(problem: CollectProblem) -> tuple[PathBuilder, Route]:
    """Algorithm 5.1–5.2 with fast placement, then every stop re-solved as the program above."""
    builder, route = lee_route(problem)

    def place(reg: Region, prev: Point2, t: float, h: float, nxt: Point2 | None, now: Point2) -> Point2:
        return convex_place(builder, reg, prev, t, h, nxt, now)

    return builder, polish(builder, route, place=place, sweeps=4)


def plan_collect_lee_convex(problem: CollectProblem) -> Plan:
    """``lee-convex``: the collection path generator with meeting points solved by SLSQP."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "lee-convex")
    _, route = lee_convex_route(problem)
    return build_collect_plan(problem, "lee-convex", route.clusters, route.positions,
                              (time.perf_counter() - t0) * 1e3)
