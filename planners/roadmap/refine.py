"""New roadmap nodes near the final stops of the roadmap search (``refine``), beyond the
dissertation: Algorithm 6.3 picks each stop among the nodes its roadmap happens to have; the
open-space planners place stops anywhere. Here each round proposes points near every stop,
makes them roadmap nodes (linked by collision-free edges like the roadmap's own, see
``RoadmapCosts.grow``) and polishes the route on the grown roadmap, so every stop stays a
roadmap node timed exactly on roadmap paths.

A stop whose legs and rover flights could run straight (no obstacle in the way) gets the point
a compass search finds on those straight lines (``RouteSpace.straight_cost``): once a node, that
point has exactly that time. Other stops get a patch of compass points, shrinking round by round.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from planners.core.geometry import compass_search
from planners.core.plan import Plan
from planners.roadmap.route import RoadmapRoute

REFINE_ROUNDS = 8  # rounds of local nodes around the final stops
RINGS = (1.0, 0.4)  # compass points at these fractions of a stop's step, every round
REFINE_TOL = 1e-3  # m: the compass steps stop shrinking here
REFINE_NODES = 600  # nodes the refinement adds at most
REFINE_GAIN = 1e-2  # s: after REFINE_PATIENCE rounds in a row that gain less than this, the search stops
REFINE_PATIENCE = 2
DESCENTS = 6  # alternations of the straight and the turned compass search
COMPASS = tuple((math.cos(a * math.pi / 8), math.sin(a * math.pi / 8)) for a in range(16))  # directions


def refine(route: RoadmapRoute, build: Callable[[Sequence[tuple[int, list[int]]]], Plan], best: Plan,
           stop: Callable[[], bool] | None = None) -> tuple[Plan, RoadmapRoute]:
    """New roadmap nodes near the final stops, then the polish, for up to ``REFINE_ROUNDS`` rounds
    while the route gets faster. A stop whose legs and rover flights could run straight gets the
    point a compass search finds on those straight lines (``RouteSpace.straight_cost``, from the
    stop and ch. 4's open-space points for its actual neighbours); any other stop gets a patch of
    16 compass points at ``RINGS`` fractions of its step around it, the step shrinking while the
    stop stays. Every new node is linked by collision-free edges (a patch's to the nodes close
    by and to the stop's targets) and timed on the roadmap exactly.
    No round starts after ``stop()``. Returns the fastest plan built on the way (``build``),
    ``best`` included, and the last route (timed on the grown roadmap)."""
    space = route.space
    costs, w = space.costs, space.costs.w
    best = _faster_plan(best, build(route.order()))
    n = len(route.clusters)
    steps = [max(float(np.min(w.rho[m])) / 4, 0.05) for m in route.clusters]
    todo = set(range(n))
    added = slow = 0
    for _ in range(REFINE_ROUNDS):
        if not todo or (stop is not None and stop()):
            break
        grown = 0
        proposed = [(k, *_proposals(route, k, steps[k])) for k in sorted(todo)]  # before the roadmap grows
        for k, pts, patch in proposed:
            if added + grown + len(pts) > REFINE_NODES:
                continue
            if patch:  # a dense patch: linked close by, and to the stop's targets like the roadmap's nodes
                grown += costs.grow(pts, 3 * steps[k], [w.node(i) for i in route.clusters[k]], w.d_edge)
            else:
                grown += costs.grow(pts, w.d_edge)
        if not grown:
            break
        added += grown
        before, span = route.nodes, route.makespan
        # the polish near the new nodes (the stops proposed for and their neighbours)
        around = {j for k in todo for j in (k - 1, k, k + 1) if 0 <= j < n}
        route = space.polish(space.timed(route.clusters, route.nodes, None, 0), stops=around)
        slow = slow + 1 if route.makespan > span - REFINE_GAIN else 0  # (re-timed on the grown roadmap)
        if slow >= REFINE_PATIENCE:
            best = _faster_plan(best, build(route.order()))
            break
        moved = {k for k in range(n) if route.nodes[k] != before[k]}
        steps = [h if k in moved or k not in todo else h * RINGS[-1] / 2 for k, h in enumerate(steps)]
        best = _faster_plan(best, build(route.order()))
        # again: the stops that moved, their neighbours, and the stops still shrinking a step
        todo = {j for k in moved for j in (k - 1, k, k + 1) if 0 <= j < n}
        todo |= {k for k in range(n) if steps[k] >= REFINE_TOL and not _straight(route, k)}
    return best, route


def _straight(route: RoadmapRoute, k: int) -> bool:
    x, y = route.positions[k]
    return math.isfinite(route.space.straight_cost(route, k)(x, y))


def _proposals(route: RoadmapRoute, k: int, step: float) -> tuple[np.ndarray, bool]:
    """Candidate new nodes for stop k (see ``refine``), and whether they are a dense patch
    around it (not one point found on straight lines)."""
    space, w = route.space, route.space.costs.w
    members = route.clusters[k]
    x, y = route.positions[k]
    cost = space.straight_cost(route, k)
    here = cost(x, y)
    if math.isfinite(here):
        prev = space.start if k == 0 else route.positions[k - 1]
        nxt = route.positions[k + 1] if k + 1 < len(route.clusters) else None
        for p in w.open_space_points(members, prev, nxt):  # ch. 4's jumps
            t = cost(*p)
            if t < here - 1e-9:
                (x, y), here = p, t
        x, y = _descend(cost, x, y, here, max(float(np.min(w.rho[members])) / 4, 0.05))
        return np.array([[x, y]]), False
    if step < REFINE_TOL:
        return np.zeros((0, 2)), True
    return np.array([(x + f * step * dx, y + f * step * dy) for f in RINGS for dx, dy in COMPASS]), True


def _descend(cost: Callable[[float, float], float], x: float, y: float, best: float,
             step: float) -> tuple[float, float]:
    """``compass_search`` from (x, y), then again with its 8 directions turned by 22.5°, while
    that helps: at a stop equidistant from several rovers the descent lies in a narrow cone."""
    for _ in range(DESCENTS):
        x, y, best = compass_search(cost, x, y, best, step, REFINE_TOL)
        turned = _Turned(cost, x, y)
        u, v, t = compass_search(turned, 0.0, 0.0, best, step, REFINE_TOL)
        if t >= best - 1e-9:
            break
        (x, y), best = turned.point(u, v), t
    return x, y


class _Turned:
    """``cost`` in coordinates turned by 22.5° about (x0, y0)."""

    C, S = math.cos(math.pi / 8), math.sin(math.pi / 8)

    def __init__(self, cost: Callable[[float, float], float], x0: float, y0: float) -> None:
        self.cost, self.x0, self.y0 = cost, x0, y0

    def point(self, u: float, v: float) -> tuple[float, float]:
        return self.x0 + self.C * u - self.S * v, self.y0 + self.S * u + self.C * v

    def __call__(self, u: float, v: float) -> float:
        return self.cost(*self.point(u, v))


def _faster_plan(a: Plan, b: Plan) -> Plan:
    return b if b.makespan < a.makespan - 1e-9 else a
