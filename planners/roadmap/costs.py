"""Roadmap costs for the search of the graph planners, memoised (dissertation ch. 6 paths, timed
by ``planners.core.timing``).

The cost of a pair of roadmap nodes is a shortest path, shortcut by Algorithm 6.2: the search
asks for the same pairs thousands of times, so each pair's ground path is computed once
(bounded caches, emptied when they fill up and whenever the roadmap grows). Times are the plan's
own: ``carrier_leg`` over the carrier's shortcut path, ``leg_time`` of √(L² + z²) for a rover
flying the shortcut ground path L of its node pair (see ``planners.roadmap.deploy``).

Candidate stops are scored first on estimates: the straight line where it is free of obstacles,
else the roadmap path length (the shortcut path lies between the two).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from planners.core.problem import CarrierSpec, Motion, Point2, Vec3
from planners.core.timing import carrier_leg, leg_time
from planners.roadmap.graph import MAX_EDGES, MAX_NODES
from planners.roadmap.world import GraphWorld, ground_path, rover_ground_path

PAIRS = 200_000  # node pairs remembered (their shortcut paths) before the cache starts again
ROWS = 50_000  # estimate vectors remembered (one per source node and cluster)
CLUSTERS = 20_000  # candidate sets remembered (one per cluster of targets)


class RoadmapCosts:
    """Memoised paths, times and candidate stops on one ``GraphWorld``'s roadmap.

    ``toward`` is True when rovers fly from the stop to their target (deployment), False when
    they fly from where they are to the stop (collection): a shortcut path depends on its
    direction.
    """

    def __init__(self, w: GraphWorld, carrier: CarrierSpec, rover: Motion, toward: bool) -> None:
        self.w, self.carrier, self.rover, self.toward = w, carrier, rover, toward
        self.z = w.targets[:, 2]
        self._rover_est: dict[int, np.ndarray] = {}  # per target, one entry per node (see _clear)
        self._clear()

    def _clear(self) -> None:
        """Drop every remembered cost but ``_rover_est``: a node's estimate there is made once
        (the roadmap only grows: nodes that served a target still do; the rare old node that a
        new shortcut brings within reach is not offered)."""
        self._paths: dict[tuple[int, int], list[Vec3]] = {}
        self._legs: dict[tuple[int, int, float], tuple[float, float]] = {}
        self._flights: dict[tuple[int, int], float] = {}
        self._stop_rovers: dict[tuple[tuple[int, ...], int], float] = {}
        self._carrier_est: dict[tuple[int, tuple[int, ...]], np.ndarray] = {}
        self._carrier_low: dict[tuple[int, tuple[int, ...]], np.ndarray] = {}
        self._rovers_low: dict[tuple[int, ...], np.ndarray] = {}
        self._serving: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = {}

    # ------------------------------------------------------------------ exact (the plan's times)

    def path(self, a: int, b: int) -> list[Vec3]:
        """The carrier's ground path a → b: a shortest roadmap path, shortcut (Algorithm 6.2) in
        the direction driven. The path comes from b's shortest-path tree when that one is at hand
        and a's is not (the polish tries many nodes between two fixed stops: one tree each side)."""
        got = self._paths.get((a, b))
        if got is None:
            if len(self._paths) >= PAIRS:
                self._paths.clear()
            rm = self.w.rm
            nodes = rm.path(b, a)[::-1] if rm.has_tree(b) and not rm.has_tree(a) else rm.path(a, b)
            got = self._paths[(a, b)] = ground_path(rm.shortcut(nodes))
        return got

    def rover_path(self, target: int, node: int) -> list[Point2]:
        """Target's rover route between its node and a stop at ``node`` (``rover_ground_path``)."""
        return rover_ground_path(self.w.rm, node, self.w.node(target), self.toward)

    def leg(self, a: int, b: int, heading: float) -> tuple[float, float]:
        """``carrier_leg`` of the path a → b: its time and the heading at b."""
        if self.carrier.turn_rate is not None:  # the time depends on the heading
            key = (a, b, heading)
            got = self._legs.get(key)
            if got is None:
                if len(self._legs) >= PAIRS:
                    self._legs.clear()
                got = self._legs[key] = carrier_leg(self.path(a, b), heading, self.carrier)
            return got
        key = (a, b, 0.0)  # no rotation: one entry per pair; a leg without motion keeps the heading
        got = self._legs.get(key)
        if got is None:
            if len(self._legs) >= PAIRS:
                self._legs.clear()
            path = self.path(a, b)
            t, h = carrier_leg(path, math.nan, self.carrier)
            got = self._legs[key] = (t, h)
        return got if not math.isnan(got[1]) else (got[0], heading)

    def flight(self, target: int, node: int) -> float:
        """Length of target's rover flight to or from ``node``: √(L² + z²) over the shortcut path."""
        key = (target, node)
        got = self._flights.get(key)
        if got is None:
            if len(self._flights) >= PAIRS:
                self._flights.clear()
            pts = self.rover_path(target, node)
            ground = sum(math.dist(p, q) for p, q in zip(pts, pts[1:], strict=False))
            got = self._flights[key] = math.hypot(ground, float(self.z[target]))
        return got

    def rovers(self, members: Sequence[int], node: int) -> float:
        """The longest rover flight time of a stop at ``node`` serving ``members``."""
        key = (tuple(members), node)
        got = self._stop_rovers.get(key)
        if got is None:
            if len(self._stop_rovers) >= PAIRS:
                self._stop_rovers.clear()
            # the longest flight takes longest (leg_time grows with the length)
            got = self._stop_rovers[key] = leg_time(max(self.flight(i, node) for i in members), self.rover)
        return got

    # ------------------------------------------------------------------ estimates

    def carrier_to(self, source: int, members: Sequence[int]) -> np.ndarray:
        """Estimated carrier time from ``source`` to each node that serves ``members`` (in the
        order of ``serving``; rotation left out)."""
        key = (source, tuple(sorted(members)))
        got = self._carrier_est.get(key)
        if got is None:
            if len(self._carrier_est) >= ROWS:
                self._carrier_est.clear()
            nodes = self.serving(members)[0]
            motion = self.carrier.motion
            got = np.array([leg_time(float(s), motion) for s in self._lengths(source, nodes)])
            self._carrier_est[key] = got
        return got

    def carrier_low(self, source: int, members: Sequence[int]) -> np.ndarray:
        """A lower bound on the carrier's time from ``source`` to each node serving ``members``
        (``carrier_to``'s order): the straight line, no rotation (a path is no shorter, and
        stopping at its vertices no faster)."""
        key = (source, tuple(sorted(members)))
        got = self._carrier_low.get(key)
        if got is None:
            if len(self._carrier_low) >= ROWS:
                self._carrier_low.clear()
            xy = self.w.rm.xy
            nodes = self.serving(members)[0]
            straight = np.hypot(xy[nodes, 0] - xy[source, 0], xy[nodes, 1] - xy[source, 1])
            motion = self.carrier.motion
            got = self._carrier_low[key] = np.array([leg_time(float(s), motion) for s in straight])
        return got

    def rovers_low(self, members: Sequence[int]) -> np.ndarray:
        """A lower bound on the longest rover flight time at each node serving ``members``: every
        rover on its straight line."""
        key = tuple(sorted(members))
        got = self._rovers_low.get(key)
        if got is None:
            if len(self._rovers_low) >= CLUSTERS:
                self._rovers_low.clear()
            xy = self.w.rm.xy
            nodes = self.serving(members)[0]
            got = np.zeros(len(nodes))
            for i in members:
                t = self.w.targets[i]
                flat = np.hypot(xy[nodes, 0] - t[0], xy[nodes, 1] - t[1])
                got = np.maximum(got, [leg_time(math.hypot(float(s), float(t[2])), self.rover) for s in flat])
            self._rovers_low[key] = got
        return got

    def rovers_at(self, target: int) -> np.ndarray:
        """Estimated flight time of ``target``'s rover for a stop at every node, inf out of its reach
        (the greedy's test of a stop serving: the roadmap path at most the target's ground radius)."""
        got = self._rover_est.get(target)
        n = self.w.rm.n_nodes
        if got is None or len(got) < n:  # none yet, or the roadmap grew: the nodes added since
            old = 0 if got is None else len(got)
            rho = float(self.w.rho[target])
            node = self.w.node(target)
            near = old + np.flatnonzero(self.w.rm.shortest(node)[0][old:] <= rho)
            z = float(self.z[target])
            more = np.full(n - old, math.inf)
            lengths = self._lengths(node, near)
            more[near - old] = [leg_time(math.hypot(float(s), z), self.rover) for s in lengths]
            got = self._rover_est[target] = more if got is None else np.concatenate([got, more])
        return got

    def _lengths(self, node: int, among: np.ndarray) -> np.ndarray:
        """From ``node`` to each of ``among``: the straight-line length where that segment is free,
        else the roadmap path length."""
        rm = self.w.rm
        d = rm.shortest(node)[0][among]
        xy = rm.xy
        straight = np.hypot(xy[among, 0] - xy[node, 0], xy[among, 1] - xy[node, 1])
        free = self.w.ws.segments_free(np.repeat(xy[node:node + 1], len(among), axis=0), xy[among])
        return np.minimum(np.where(free, straight, d), d)

    def serving(self, members: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """Roadmap nodes from which one stop serves every member (the greedy's rule: each along the
        roadmap within its ground radius), and the stop's estimated longest rover flight there."""
        key = tuple(sorted(members))
        got = self._serving.get(key)
        if got is None:
            if len(self._serving) >= CLUSTERS:
                self._serving.clear()
            worst = self.rovers_at(key[0])
            for i in key[1:]:
                worst = np.maximum(worst, self.rovers_at(i))
            nodes = np.flatnonzero(np.isfinite(worst))
            got = self._serving[key] = (nodes, worst[nodes])
        return got

    def fits(self, members: Sequence[int]) -> bool:
        return len(self.serving(members)[0]) > 0

    # ------------------------------------------------------------------ growing the roadmap

    def grow(self, points: np.ndarray, radius: float, to: Sequence[int] = (), to_radius: float = 0.0) -> int:
        """Add collision-free ``points`` as roadmap nodes, linked to every node up to ``radius``
        away and to the nodes ``to`` up to ``to_radius``, when the roadmap stays within its
        limits; every remembered cost is dropped. Returns the nodes added."""
        rm = self.w.rm
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        pts = pts[self.w.ws.points_free(pts) & self.w.ws.inside_bounds(pts)]
        if not len(pts) or rm.n_nodes + len(pts) > MAX_NODES:
            return 0
        near = int(np.sum(cKDTree(np.concatenate([rm.xy, pts])).query_ball_point(
            pts, radius, return_length=True)))
        if rm.n_edges + near // 2 + len(pts) * len(to) > MAX_EDGES:  # Roadmap.add's test, before it refuses
            return 0
        new = rm.add(pts, radius)
        if to_radius > radius:
            rm.link(new, to, to_radius, radius)
        self._clear()
        return len(pts)
