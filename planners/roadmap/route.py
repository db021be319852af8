"""A carrier route on the roadmap for the shared search moves (``planners.core.moves``/``search``).

A route is clusters in visiting order, each served from one roadmap node (global roadmap, local
PRMs and ch. 4's open-space points, as the greedy of Algorithm 6.3 builds them). It implements
the route protocol of ``planners.core.search.ClusterRoute``: ``replace(i, pieces, count)``
places the new pieces' stops (the quick placement: each piece's best node on estimated times,
given the stop before it and the one after) and re-times the route; ``accept`` takes the
candidate. Every time is the plan's own (``planners.core.timing`` through ``RoadmapCosts``):

* deployment (eq. 6.3): the carrier drives the shortcut path to the stop, unloads, the rovers
  fly; the makespan is the last rover's arrival;
* collection (eq. 5.2): every rover flies to its stop from t = 0, the carrier waits for the
  latest and loads; the makespan is the last stop's departure.

``RouteSpace.polish`` is the final per-stop polish: each stop in turn moves to the serving node
that makes the whole route fastest with the other stops fixed.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from planners.core.problem import Point2
from planners.core.timing import carrier_leg, leg_time
from planners.roadmap.costs import RoadmapCosts
from planners.roadmap.graph import Workspace
from planners.roadmap.world import node_xy

SHORTLIST = 5  # candidate nodes per stop timed exactly by the final polish (the best on estimates)
SEARCH_SHORTLIST = 3  # the same for the polish of every change the search scores
POLISH_SWEEPS = 3


@dataclasses.dataclass
class RoadmapRoute:
    """Clusters, their stop nodes and the times of every stop (index k)."""

    space: RouteSpace
    clusters: list[list[int]]
    nodes: list[int]
    positions: list[Point2]
    heading: list[float]  # carrier heading on arriving at stop k
    arrive: list[float]  # carrier arrival at stop k
    depart: list[float]  # carrier departure from stop k (collection: eta_k)
    done: list[float]  # deployment: stop k's last rover arrival; collection: its latest rover arrival
    worst: list[float]  # deployment: latest rover arrival of stops 0..k
    makespan: float

    def state_before(self, k: int) -> tuple[int, float, float, float]:
        """(node, clock, heading, latest rover arrival so far) when the carrier leaves for stop k."""
        if k == 0:
            return 0, 0.0, self.space.heading, 0.0
        return self.nodes[k - 1], self.depart[k - 1], self.heading[k - 1], self.worst[k - 1]

    def replace(self, i: int, pieces: list[list[int]], count: int = 1) -> tuple[float, RoadmapRoute]:
        """Clusters i..i+count-1 replaced by ``pieces`` (their stops placed quickly): (makespan, route)."""
        space = self.space
        node, clock, heading, worst = self.state_before(i)
        after = i + count
        nodes = []
        for j, piece in enumerate(pieces):
            if j + 1 < len(pieces):
                nxt, tail, ready = space.anchor(pieces[j + 1])
            elif after < len(self.clusters):
                nxt, tail, ready = self.nodes[after], self.tail(after), self.done[after]
            else:
                nxt, tail, ready = None, 0.0, 0.0
            best = space.place(piece, node, clock, nxt, tail, ready)
            dt, heading = space.costs.leg(node, best, heading)
            clock = space.step(clock + dt, space.costs.rovers(piece, best))[0]
            nodes.append(best)
            node = best
        clusters = self.clusters[:i] + [list(p) for p in pieces] + self.clusters[after:]
        route = space.timed(clusters, self.nodes[:i] + nodes + self.nodes[after:], self, i)
        return route.makespan, route

    def accept(self, candidate: tuple[float, RoadmapRoute]) -> RoadmapRoute:
        return candidate[1]

    def moved(self, k: int, node: int) -> RoadmapRoute:
        """This route with stop k at ``node``."""
        return self.space.timed(self.clusters, self.nodes[:k] + [node] + self.nodes[k + 1:], self, k)

    def tail(self, k: int) -> float:
        """How much later than the carrier's arrival at stop k the route ends (its stops kept)."""
        if self.space.deploy:
            return max(self.done[k:]) - self.arrive[k]
        return self.makespan - self.depart[k] + self.space.stop_time

    def order(self) -> list[tuple[int, list[int]]]:
        return [(n, list(c)) for n, c in zip(self.nodes, self.clusters, strict=True)]


class RouteSpace:
    """Everything routes of one problem share: the costs, the schedule kind, the start heading."""

    def __init__(self, costs: RoadmapCosts, heading: float, deploy: bool) -> None:
        self.costs, self.heading, self.deploy = costs, heading, deploy
        c = costs.carrier
        self.stop_time = c.deploy_stop_time if deploy else c.collect_stop_time
        self.start = node_xy(costs.w.rm, 0)

    def fits(self, members: Sequence[int]) -> bool:
        return self.costs.fits(members)

    def step(self, arrive: float, rovers: float) -> tuple[float, float, float]:
        """(departure, done, arrival) of a stop reached at ``arrive`` whose rovers fly ``rovers`` s."""
        if self.deploy:
            depart = arrive + self.stop_time
            return depart, depart + rovers, arrive
        return max(arrive, rovers) + self.stop_time, rovers, arrive

    def route(self, clusters: Sequence[Sequence[int]]) -> RoadmapRoute:
        """Every stop placed quickly, in order (the ``rebuild`` of the fine and iterated searches)."""
        empty = self.timed([], [], None, 0)
        return empty.replace(0, [list(c) for c in clusters], 0)[1] if clusters else empty

    def timed(self, clusters: list[list[int]], nodes: list[int], base: RoadmapRoute | None,
              k0: int) -> RoadmapRoute:
        """The route over ``nodes``, its times from stop k0 on computed afresh (before: ``base``'s)."""
        n = len(clusters)
        keep = k0 if base is not None else 0
        r = RoadmapRoute(self, clusters, nodes, [], [], [], [], [], [], 0.0)
        if base is not None and keep:
            r.heading, r.arrive = base.heading[:keep], base.arrive[:keep]
            r.depart, r.done, r.worst = base.depart[:keep], base.done[:keep], base.worst[:keep]
        node, clock, heading, worst = r.state_before(keep) if keep else (0, 0.0, self.heading, 0.0)
        legs, rovers = self.costs.leg, self.costs.rovers
        for k in range(keep, n):
            dt, heading = legs(node, nodes[k], heading)
            arrive = clock + dt
            clock, done, _ = self.step(arrive, rovers(clusters[k], nodes[k]))
            worst = max(worst, done)
            r.heading.append(heading)
            r.arrive.append(arrive)
            r.depart.append(clock)
            r.done.append(done)
            r.worst.append(worst)
            node = nodes[k]
        rm = self.costs.w.rm
        r.positions = [node_xy(rm, v) for v in nodes]
        r.makespan = (r.worst[-1] if self.deploy else r.depart[-1]) if n else 0.0
        return r

    def end_from(self, route: RoadmapRoute, k: int, node: int, clock: float, heading: float,
                 worst: float) -> float:
        """The makespan of ``route`` from stop k on (its nodes), the carrier leaving ``node`` at
        ``clock`` with ``heading``, the latest rover arrival so far ``worst``."""
        legs, rovers = self.costs.leg, self.costs.rovers
        for j in range(k, len(route.clusters)):
            dt, heading = legs(node, route.nodes[j], heading)
            clock, done, _ = self.step(clock + dt, rovers(route.clusters[j], route.nodes[j]))
            worst = max(worst, done)
            node = route.nodes[j]
        return worst if self.deploy else clock

    def straight_cost(self, route: RoadmapRoute, k: int) -> Callable[[float, float], float]:
        """Makespan of ``route`` with stop k at the ground point (x, y), reached and left on
        straight lines and its rovers flying straight (inf where one of those lines meets an
        obstacle or a rover is out of reach); the other stops kept. The refinement's proposals:
        where those lines are free, the point made a roadmap node has exactly this time."""
        w, c, rover = self.costs.w, self.costs.carrier, self.costs.rover
        rm = w.rm
        prev, clock, heading, worst = route.state_before(k)
        members = route.clusters[k]
        tx, rho, z = w.targets[members, :2], w.rho[members], self.costs.z[members]
        p = (float(rm.xy[prev][0]), float(rm.xy[prev][1]), 0.0)
        last = k + 1 == len(route.clusters)
        q = None if last else (*node_xy(rm, route.nodes[k + 1]), 0.0)
        ends = np.array([p[:2]] + ([] if q is None else [q[:2]]) + [tuple(t) for t in tx], dtype=float)
        # every point the search may try lies in the members' discs: with no obstacle in the box
        # around those and the ends, no line needs testing
        lo = np.minimum(ends.min(axis=0), np.max(tx - rho[:, None], axis=0))
        hi = np.maximum(ends.max(axis=0), np.min(tx + rho[:, None], axis=0))
        sight = _Sight(w.ws, ends, w.ws.rect_free((float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1]))))

        def cost(x: float, y: float) -> float:
            d = np.hypot(tx[:, 0] - x, tx[:, 1] - y)
            if np.any(d > rho) or not sight.clear(x, y):
                return math.inf
            here = (x, y, 0.0)
            dt, h = carrier_leg([p, here], heading, c)
            fly = leg_time(float(np.max(np.hypot(d, z))), rover)  # (leg_time grows with the length)
            t, done, _ = self.step(clock + dt, fly)
            top = max(worst, done)
            if q is None:
                return top if self.deploy else t
            dt, h = carrier_leg([here, q], h, c)
            t, done, _ = self.step(t + dt, self.costs.rovers(route.clusters[k + 1], route.nodes[k + 1]))
            return self.end_from(route, k + 2, route.nodes[k + 1], t, h, max(top, done))

        return cost

    # ------------------------------------------------------------------ choosing a stop's node

    def anchor(self, members: Sequence[int]) -> tuple[int, float, float]:
        """A stand-in for a stop not placed yet: the serving node with the shortest flights,
        with its (estimated) tail and rover time."""
        nodes, rovers = self.costs.serving(members)
        j = int(np.argmin(rovers))
        r = float(rovers[j])
        return int(nodes[j]), (self.stop_time + r if self.deploy else self.stop_time), r

    def scores(self, members: Sequence[int], prev: int, clock: float, nxt: int | None,
               tail: float, ready: float, low: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Serving nodes and the estimated end of the route through each (the stop before at
        ``prev`` left at ``clock``; the next stop at ``nxt``, ending ``tail`` after its arrival,
        with its rovers there at ``ready``; the stops after it shifted alike). With ``low``, a
        lower bound instead: straight lines, and the turn at the next stop all saved."""
        c = self.costs
        nodes = c.serving(members)[0]
        rovers = c.rovers_low(members) if low else c.serving(members)[1]
        there = clock + (c.carrier_low(prev, members) if low else c.carrier_to(prev, members))
        if self.deploy:
            leave = there + self.stop_time
            end = leave + rovers
        else:
            leave = np.maximum(there, rovers) + self.stop_time
            end = leave
        if nxt is not None:
            on = leave + (c.carrier_low(nxt, members) if low else c.carrier_to(nxt, members))
            if low and c.carrier.turn_rate is not None:
                on = on - math.pi / c.carrier.turn_rate
            end = np.maximum(end, on + tail) if self.deploy else np.maximum(on, ready) + tail
        return nodes, end

    def bound_through(self, route: RoadmapRoute, k: int, node: int, j: int) -> float:
        """A lower bound on the makespan of ``route`` with stop k at ``node`` (the j-th node serving
        its cluster): the leg into it and its rovers exact, the leg on to stop k + 1 straight (as
        ``scores(low=True)``), the stops after that shifted alike."""
        c = self.costs
        prev, clock, heading, _ = route.state_before(k)
        members = route.clusters[k]
        dt, _ = c.leg(prev, node, heading)
        leave, done, _ = self.step(clock + dt, c.rovers(members, node))
        if k + 1 == len(route.clusters):
            return done if self.deploy else leave
        on = leave + float(c.carrier_low(route.nodes[k + 1], members)[j])
        if c.carrier.turn_rate is not None:
            on -= math.pi / c.carrier.turn_rate
        if self.deploy:
            return max(done, on + route.tail(k + 1))
        return max(on, route.done[k + 1]) + route.tail(k + 1)

    def place(self, members: Sequence[int], prev: int, clock: float, nxt: int | None,
              tail: float, ready: float) -> int:
        """The quick placement: the node with the earliest estimated end."""
        nodes, end = self.scores(members, prev, clock, nxt, tail, ready)
        return int(nodes[int(np.argmin(end))])

    def polish(self, route: RoadmapRoute, shortlist: int = SHORTLIST,
               stops: Iterable[int] | None = None) -> RoadmapRoute:
        """Each stop in turn (of ``stops``, default all) on the serving node that makes the whole
        route fastest, the others fixed (the ``shortlist`` best nodes on estimates timed exactly);
        then again the stops next to one that moved, until none moves (``POLISH_SWEEPS`` at most)."""
        n = len(route.clusters)
        todo = set(range(n) if stops is None else stops)
        for _ in range(POLISH_SWEEPS):
            moved = set()
            for k in sorted(todo):
                prev, clock, _, _ = route.state_before(k)
                last = k + 1 == n
                nxt = None if last else route.nodes[k + 1]
                tail = 0.0 if last else route.tail(k + 1)
                ready = 0.0 if last else route.done[k + 1]
                nodes, end = self.scores(route.clusters[k], prev, clock, nxt, tail, ready)
                _, low = self.scores(route.clusters[k], prev, clock, nxt, tail, ready, low=True)
                for j in np.argsort(end, kind="stable")[:shortlist]:
                    node = int(nodes[j])
                    if node == route.nodes[k] or low[j] >= route.makespan - 1e-9 \
                            or self.bound_through(route, k, node, int(j)) >= route.makespan - 1e-9:
                        continue  # (a bound: it cannot make the route faster)
                    cand = route.moved(k, node)
                    if cand.makespan < route.makespan - 1e-9:
                        route = cand
                        moved.add(k)
            todo = {j for k in moved for j in (k - 1, k, k + 1) if 0 <= j < n}
            if not todo:
                break
        return route


class _Sight:
    """Whether the straight lines from a point to fixed ends are collision-free, for a search that
    tries many points close together: a box around a point whose fans to every end are free
    answers for every point in it (``Workspace.fans_free``)."""

    BOX = 0.25  # m: half the side of the box tried around a point

    def __init__(self, ws: Workspace, ends: np.ndarray, everywhere: bool) -> None:
        self.ws, self.ends, self.everywhere = ws, ends, everywhere
        self.boxes: list[tuple[float, float, float, float]] = []

    def clear(self, x: float, y: float) -> bool:
        if self.everywhere or any(x0 <= x <= x1 and y0 <= y <= y1 for x0, y0, x1, y1 in self.boxes):
            return True
        h = self.BOX
        if self.ws.fans_free((x - h, y - h), (x + h, y + h), self.ends):
            self.boxes.append((x - h, y - h, x + h, y + h))
            return True
        return bool(np.all(self.ws.segments_free(np.repeat([[x, y]], len(self.ends), axis=0), self.ends)))
