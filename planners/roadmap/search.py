"""The search after the greedy of Algorithm 6.3, shared by the deployment and collection graph
planners: the moves of the open-space planners (``planners.core.moves``: relocate, exchange,
split-off, split, merge, swap, shift, reverse; ``planners.core.search.reorder``) on a
``RoadmapRoute``, each change's stops chosen among the roadmap's nodes, then the per-stop polish
and, last, local PRMs around the final stops (``refine``).

Only improvements are kept, and the caller keeps the greedy's plan when the search does not
beat it. With a time budget (``budget_ms``) the iterated local search runs until it is spent.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Sequence

import numpy as np

from planners.core.geometry import compass_search
from planners.core.moves import deadline, fine_descent, iterated_search, quick_descent, remembered
from planners.core.plan import Plan
from planners.core.search import reorder
from planners.roadmap.route import SEARCH_SHORTLIST, RoadmapRoute, RouteSpace

FINE_MOVES_UPTO = 8  # targets: up to this many, every move is also scored on polished stops
ILS_PATIENCE = 20  # kicks per target without a new best before the anytime search gives up
REFINE_ROUNDS = 8  # rounds of local nodes around the final stops
RINGS = (1.0, 0.4)  # compass points at these fractions of a stop's step, every round
REFINE_SAMPLES = 8  # random nodes per stop in the first round
REFINE_TOL = 1e-3  # m: the compass steps stop shrinking here
REFINE_NODES = 400  # nodes the refinement adds at most
REFINE_GAIN = 1e-2  # s: after REFINE_PATIENCE rounds in a row that gain less than this, the search stops
REFINE_PATIENCE = 2
DESCENTS = 6  # alternations of the straight and the turned compass search
COMPASS = tuple((math.cos(a * math.pi / 8), math.sin(a * math.pi / 8)) for a in range(16))  # directions


def search(route: RoadmapRoute, build: Callable[[Sequence[tuple[int, list[int]]]], Plan], greedy: Plan,
           budget_ms: float | None, seed: int, local: bool, t0: float | None = None) -> Plan:
    """The search after the greedy: the moves on ``route`` (``improve``), new roadmap nodes near
    the stops (``refine``); with a budget, then the iterated local search until it is spent and
    the refinement of what it found. The fastest plan built (``build``), ``greedy`` included."""
    stop = deadline(budget_ms, t0)
    plan, route = refine(improve(route, stop), build, greedy, local)
    if stop is None or stop() or sum(len(c) for c in route.clusters) < 2:
        return plan
    space = route.space
    finish = remembered(lambda r: space.polish(r, SEARCH_SHORTLIST))
    better = iterated_search(route, space.fits, space.route, finish, random.Random(seed), stop,
                             max_fails=ILS_PATIENCE * sum(len(c) for c in route.clusters))
    if better.makespan < route.makespan - 1e-9:
        plan, _ = refine(better, build, plan, local, stop)
    return plan


def improve(route: RoadmapRoute, stop: Callable[[], bool] | None = None) -> RoadmapRoute:
    """The moves on ``route`` (the greedy's) until none makes it faster, each change's stops
    polished (``RouteSpace.polish``); as in the open-space planners, the quick descent always
    runs to its end and ``stop`` (a budget's deadline) bounds the fine descent of long routes."""
    space = route.space
    n = sum(len(c) for c in route.clusters)
    if n < 2:
        return space.polish(route)
    finish = remembered(lambda r: space.polish(r, SEARCH_SHORTLIST))
    best = finish(route)
    moved = quick_descent(route, space.fits)
    moved = reorder(moved, moved.positions, space.start, space.route)
    best = _faster(best, finish(moved))
    if n <= FINE_MOVES_UPTO or stop is not None:
        best = fine_descent(best, space.fits, space.route, finish, stop if n > FINE_MOVES_UPTO else None,
                            slack=0.15 if stop is None else math.inf)
    return best


def refine(route: RoadmapRoute, build: Callable[[Sequence[tuple[int, list[int]]]], Plan], best: Plan,
           local: bool, stop: Callable[[], bool] | None = None) -> tuple[Plan, RoadmapRoute]:
    """New roadmap nodes near the final stops, then the polish, for up to ``REFINE_ROUNDS`` rounds
    while the route gets faster. A stop whose legs and rover flights could run straight gets the
    point a compass search finds on those straight lines (``RouteSpace.straight_cost``, from the
    stop and ch. 4's open-space points for its actual neighbours); any other stop gets
    ``REFINE_SAMPLES`` local-PRM samples around it (eq. 6.7, when the planner uses local PRMs) and
    the 16 compass points at ``RINGS`` fractions of its step, the step shrinking while the stop
    stays. Every new node is linked like the roadmap's own and timed on it exactly.
    No round starts after ``stop()``. Returns the fastest plan built on the way (``build``),
    ``best`` included, and the last route (timed on the grown roadmap)."""
    space = route.space
    costs, w = space.costs, space.costs.w
    best = _faster_plan(best, build(route.order()))
    n = len(route.clusters)
    steps = [max(float(np.min(w.rho[m])) / 4, 0.05) for m in route.clusters]
    todo = set(range(n))
    added = slow = 0
    for first in range(REFINE_ROUNDS):
        if not todo or added > REFINE_NODES or (stop is not None and stop()):
            break
        grown = 0
        for k in sorted(todo):
            pts, near = _proposals(route, k, steps[k], local and first == 0)
            if near:  # a dense patch: linked close by, and to the stop's targets like the roadmap's nodes
                grown += costs.grow(pts, 3 * steps[k], [w.node(i) for i in route.clusters[k]], w.d_edge)
            else:
                grown += costs.grow(pts, w.d_edge)
        if not grown:
            break
        added += grown
        before, span = route.nodes, route.makespan
        route = space.polish(space.timed(route.clusters, route.nodes, None, 0))
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


def _proposals(route: RoadmapRoute, k: int, step: float, local: bool) -> tuple[np.ndarray, bool]:
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
    out = [np.array([(x + f * step * dx, y + f * step * dy) for f in RINGS for dx, dy in COMPASS])]
    if local:
        box = 2 * step
        out.append(w.ws.sample(w.rng, REFINE_SAMPLES, (x - box, y - box), (x + box, y + box)))
    return np.concatenate(out), True


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


def _open_around(space: RouteSpace, members: Sequence[int]) -> bool:
    w = space.costs.w
    mem = list(members)
    xy, rho = w.targets[mem, :2], w.rho[mem]
    lo = (float(np.max(xy[:, 0] - rho)), float(np.max(xy[:, 1] - rho)))
    hi = (float(np.min(xy[:, 0] + rho)), float(np.min(xy[:, 1] + rho)))
    return lo[0] <= hi[0] and lo[1] <= hi[1] and w.ws.rect_free(lo, hi)


def _faster(a: RoadmapRoute, b: RoadmapRoute) -> RoadmapRoute:
    return b if b.makespan < a.makespan - 1e-9 else a


def _faster_plan(a: Plan, b: Plan) -> Plan:
    return b if b.makespan < a.makespan - 1e-9 else a

