"""Re-placing a short deployment route's stops on the smoothed makespan (``planners.core.smooth``)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from planners.core.plan import SNAP
from planners.core.problem import Point2
from planners.core.smooth import smooth_compass, smooth_max
from planners.core.timing import carrier_hop, leg_time
from planners.deploy.path import PathBuilder, Route

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

