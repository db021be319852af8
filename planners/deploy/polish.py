"""Re-placing a short deployment route's stops on the smoothed makespan (``planners.core.smooth``)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from planners.core.problem import Point2
from planners.core.smooth import smooth_compass, smooth_max
from planners.core.timing import carrier_hop
from planners.deploy.path import PathBuilder, Route


def smooth(builder: PathBuilder, route: Route, tol: float = 1e-3) -> Route:
    """Every stop of ``route`` re-placed on the smoothed makespan (the latest last arrival): where
    two stops' rovers arrive last together, one stop moving alone cannot help. Keeps the faster
    of the two routes."""
    if not route.clusters:
        return route
    inst, unload, carrier = builder.inst, builder.unload, builder.carrier
    clusters, d = route.clusters, inst.d

    def cost(pos: Sequence[Point2], tau: float) -> float:
        prev, h, t, worst = builder.start, inst.problem.heading, 0.0, -math.inf
        for members, q in zip(clusters, pos, strict=True):
            reach = inst.reach_from(q, members)
            if reach > d:
                return math.inf
            dt, h = carrier_hop(prev, q, h, carrier)
            t += dt + unload
            worst = smooth_max(worst, t + builder.finish(q, members), tau)
            prev = q
        return worst

    def exact(pos: Sequence[Point2]) -> float:
        return cost(pos, 0.0)

    pos = smooth_compass(cost, exact, route.positions, max(d / 4, 0.05), tol)
    cand = Route(builder, clusters, route.geos, pos)
    return cand if cand.makespan < route.makespan - 1e-9 else route
