"""Re-placing a collection route's stops once both neighbours are known (dissertation ch. 5.5.1)."""

from __future__ import annotations

import math
from collections.abc import Callable

from planners.collect.path import PathBuilder, Route
from planners.collect.reach import Point2, Region


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
