"""Deployment among obstacles on a probabilistic roadmap (dissertation ch. 6, Algorithm 6.3).

Planner name ``lee-graph``. The carrier drives roadmap paths (shortcut by Algorithm 6.2); every
distance is a roadmap path length. Rover flights follow the roadmap too:

Rover routes in 3D (a choice the chapter leaves open): walls have unlimited height, so only the
ground projection of a flight matters for collisions. A rover flies the shortcut roadmap path
from its deploy node to its task and climbs evenly along it — the straight 3D line of ch. 4
unrolled along the ground polyline. Its length is √(L² + z²) for a ground length L and task
height z, so a rover reaches task i from a node within ground path length ρᵢ = √(d² − zᵢ²).
With no obstacle in between the path is the single straight 3D segment of the open-space
planners.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np

from planners.core.clustering import divide_cluster
from planners.core.geometry import enclosing_ball
from planners.core.plan import Plan, RoverLeg, Stop
from planners.core.problem import DeployProblem, PlanningError, Point2
from planners.core.timing import RANGE_MARGIN, carrier_leg, leg_time, retime
from planners.roadmap.costs import RoadmapCosts
from planners.roadmap.search import search_greedy
from planners.roadmap.world import GraphWorld, ground_path, node_xy


class _Deploy:
    """Algorithm 6.3 for one problem; the carrier's state after the stops committed so far."""

    def __init__(self, p: DeployProblem, local: bool) -> None:
        self.p = p
        d = p.deploy_range
        tasks = np.array([t.position for t in p.tasks], dtype=float).reshape(-1, 3)
        for t in p.tasks:
            if t.position[2] < 0 or t.position[2] > d:
                raise PlanningError(f"task {t.id} at height {t.position[2]:g} m cannot be reached with a "
                                    f"deploy range of {d:g} m")
        self.d_eff = max(d - RANGE_MARGIN, 0.0)
        rho = np.sqrt(np.maximum(self.d_eff**2 - tasks[:, 2] ** 2, 0.0))
        self.w = GraphWorld(p.obstacles, p.bounds, p.start, tasks, [t.id for t in p.tasks], "task", rho, d,
                            p.roadmap, p.seed, local)
        self.z = tasks[:, 2]
        # carrier state after the committed stops
        self.prev = 0
        self.t = 0.0
        self.heading = p.heading
        self.worst = 0.0
        self.stops: list[tuple[int, list[int]]] = []

    def rover_time(self, mem: Sequence[int], dist: np.ndarray, node: int) -> float:
        """Longest rover flight time from ``node`` to the members (ground path L, climb z)."""
        return max(leg_time(math.hypot(dist[k, node], self.z[i]), self.p.rover) for k, i in enumerate(mem))

    def commit(self, node: int, mem: list[int], dist: np.ndarray) -> None:
        path = ground_path(self.w.rm.smoothed_path(self.prev, node))  # Algorithm 6.2
        dt, self.heading = carrier_leg(path, self.heading, self.p.carrier)
        self.t += dt + self.p.carrier.deploy_stop_time
        self.worst = max(self.worst, self.t + self.rover_time(mem, dist, node))
        self.stops.append((node, mem))
        self.prev = node

    def exact_single(self, node: int, mem: list[int], dist: np.ndarray) -> float:
        """Makespan if the carrier's last stop is ``node`` serving ``mem`` (eq. 6.3)."""
        path = ground_path(self.w.rm.smoothed_path(self.prev, node))
        dt, _ = carrier_leg(path, self.heading, self.p.carrier)
        t = self.t + dt + self.p.carrier.deploy_stop_time
        return max(self.worst, t + self.rover_time(mem, dist, node))

    def cluster(self, remaining: list[int]) -> tuple[list[int], int]:
        """Cluster creation: the nearest task along the roadmap (eq. 6.8) and every remaining task
        closer than 2·d_deploy to it."""
        d_prev = self.w.rm.shortest(self.prev)[0]
        nearest = min(remaining, key=lambda i: (d_prev[self.w.node(i)], i))
        tx = self.w.targets
        mem = [nearest] + [i for i in remaining if i != nearest
                           and math.dist(tx[i, :2], tx[nearest, :2]) < 2 * self.p.deploy_range]
        return mem, nearest

    def serve(self, mem: list[int], nearest: int,
              nxt: Point2 | None) -> tuple[list[int], np.ndarray, np.ndarray]:
        """Candidates for the cluster, dividing it (Algorithm 6.1) while no node serves it all."""
        prev_xy = node_xy(self.w.rm, self.prev)
        while True:
            cands, dist = self.w.candidates(mem, prev_xy, nxt)
            if len(cands):
                return mem, cands, dist
            mem = self.w.divide(mem, nearest)

    def run(self) -> list[tuple[int, list[int]]]:
        remaining = list(range(len(self.p.tasks)))
        tx = self.w.targets
        while remaining:
            mem, nearest = self.cluster(remaining)
            rest = [i for i in remaining if i not in mem]
            nxt = self.next_nearest(mem, rest)
            mem, cands, dist = self.serve(mem, nearest, None if nxt is None else
                                          (float(tx[nxt, 0]), float(tx[nxt, 1])))
            rest = [i for i in remaining if i not in mem]
            if rest:
                # eq. 6.10: the candidate on the shortest way from the previous stop to the next task
                nxt = self._nearest_to_centre(mem, rest)
                d_prev = self.w.rm.shortest(self.prev)[0]
                d_next = self.w.rm.shortest(self.w.node(nxt))[0]
                dist_full = self._member_dist(mem)
                node = int(cands[np.argmin(d_prev[cands] + d_next[cands])])
                self.commit(node, mem, dist_full)
                remaining = rest
                continue
            # the last cluster (Fig. 6.6): one stop, or two stops for its two halves
            done = self.last_cluster(mem, cands)
            remaining = [i for i in remaining if i not in done]
        return self.stops

    def next_nearest(self, mem: Sequence[int], rest: Sequence[int]) -> int | None:
        """The remaining task nearest the centre of the cluster's enclosing circle (eq. 6.9)."""
        return self._nearest_to_centre(mem, rest) if rest else None

    def _nearest_to_centre(self, mem: Sequence[int], rest: Sequence[int]) -> int:
        tx = self.w.targets
        lam = enclosing_ball([tuple(tx[i, :2]) for i in mem]).center
        return min(rest, key=lambda i: (math.dist(tx[i, :2], lam), i))

    def _member_dist(self, mem: Sequence[int]) -> np.ndarray:
        return self.w.rm.distances([self.w.node(i) for i in mem])

    def last_cluster(self, mem: list[int], cands: np.ndarray) -> list[int]:
        """Commit the last cluster's stop(s); returns the tasks served."""
        prev_xy = node_xy(self.w.rm, self.prev)
        split = None
        if len(mem) >= 2:
            pts = [tuple(p) for p in self.w.targets]
            c1, c2 = divide_cluster(mem, pts, (*prev_xy, 0.0))  # by geographic adjacency (Alg. 3.1)
            lam2 = enclosing_ball([pts[i][:2] for i in c2]).center
            k1, _ = self.w.candidates(c1, prev_xy, (float(lam2[0]), float(lam2[1])))
            k2, _ = self.w.candidates(c2, prev_xy, None)
            if len(k1) and len(k2):
                split = (c1, c2)
        # every local PRM is done: path lengths on the final graph
        cands = self._refilter(mem, cands)
        dist = self._member_dist(mem)
        single = min(((self.exact_single(int(c), mem, dist), int(c)) for c in cands), default=None)
        best_split = self._best_split(*split) if split is not None else None
        if single is None and best_split is None:
            raise PlanningError("no stop serves the last tasks")  # unreachable: a task's own node serves it
        if best_split is not None and (single is None or best_split[0] < single[0] - 1e-9):
            _, n1, c1, n2, c2 = best_split
            self.commit(n1, c1, self._member_dist(c1))
            return list(c1)  # the second half is clustered again (it may split once more)
        assert single is not None
        self.commit(single[1], mem, dist)
        return mem

    def _refilter(self, mem: Sequence[int], nodes: np.ndarray) -> np.ndarray:
        """Keep the nodes that still serve every member (they only get closer as the graph grows)."""
        dist = self._member_dist(mem)
        rho = self.w.rho[list(mem)]
        ok = np.all(dist[:, nodes] <= rho[:, None], axis=0) if len(nodes) else np.zeros(0, dtype=bool)
        return nodes[ok]

    def _serving(self, mem: Sequence[int]) -> np.ndarray:
        """All roadmap nodes that serve every member."""
        dist = self._member_dist(mem)
        return np.flatnonzero(np.all(dist <= self.w.rho[list(mem)][:, None], axis=0))

    def _best_split(self, c1: list[int],
                    c2: list[int]) -> tuple[float, int, list[int], int, list[int]] | None:
        """Fig. 6.6b: stops n1 (first half) and n2 (second half) minimising the later of the two
        halves' last arrivals — estimated on roadmap lengths, then timed exactly for the best pair."""
        k1, k2 = self._serving(c1), self._serving(c2)
        if not len(k1) or not len(k2):
            return None
        cr, unload = self.p.carrier, self.p.carrier.deploy_stop_time
        d1, d2 = self._member_dist(c1), self._member_dist(c2)
        r1 = np.array([self.rover_time(c1, d1, int(n)) for n in k1])
        r2 = np.array([self.rover_time(c2, d2, int(n)) for n in k2])
        d_prev = self.w.rm.shortest(self.prev)[0]
        t1 = self.t + np.array([leg_time(d_prev[n], cr.motion) for n in k1]) + unload
        between = self.w.rm.distances([int(n) for n in k1])[:, k2]
        legs = np.vectorize(lambda s: leg_time(float(s), cr.motion))(between) if between.size else between
        t2 = t1[:, None] + legs + unload + r2[None, :]
        est = np.maximum(np.maximum(self.worst, t1 + r1)[:, None], t2)
        a, b = np.unravel_index(int(np.argmin(est)), est.shape)
        n1, n2 = int(k1[a]), int(k2[b])
        # exact time of the pair over the shortcut paths
        save = (self.prev, self.t, self.heading, self.worst, list(self.stops))
        self.commit(n1, c1, d1)
        total = self.exact_single(n2, c2, d2)
        self.prev, self.t, self.heading, self.worst, self.stops = save
        return total, n1, c1, n2, c2


def plan_lee_graph(problem: DeployProblem, local_prm: bool = True, search: bool = True) -> Plan:
    """Algorithm 6.3 on a probabilistic roadmap, planner name ``lee-graph``; with ``search``, then
    the moves of the open-space planners on the roadmap (``planners.roadmap.search``), kept when
    they make the plan faster."""
    t0 = time.perf_counter()
    if len(problem.rover_ids()) < len(problem.tasks):
        raise PlanningError(f"{len(problem.tasks)} tasks need as many rovers, only "
                            f"{len(problem.rover_ids())} on the carrier")
    if not problem.tasks:
        return Plan(kind="deploy", planner="lee-graph", start=problem.start, heading=problem.heading,
                    stops=[])
    dep = _Deploy(problem, local_prm)
    order = dep.run()
    costs = RoadmapCosts(dep.w, problem.carrier, problem.rover, toward=True)
    plan = build_graph_plan(problem, dep.w, order, costs)
    if search:
        plan = search_greedy(order, costs, problem.heading, True,
                             lambda o: build_graph_plan(problem, dep.w, o, costs), plan,
                             problem.budget_ms, problem.seed, t0)
    plan.compute_ms = (time.perf_counter() - t0) * 1e3
    return plan


def build_graph_plan(problem: DeployProblem, w: GraphWorld, order: Sequence[tuple[int, Sequence[int]]],
                     costs: RoadmapCosts | None = None) -> Plan:
    """Carrier sub-routes and rover routes on the final roadmap, shortcut, and timed (eq. 6.3); the
    paths the search timed (``costs``) when given."""
    rm = w.rm
    costs = costs or RoadmapCosts(w, problem.carrier, problem.rover, toward=True)
    rover_ids = iter(problem.rover_ids())
    stops: list[Stop] = []
    prev = 0
    for node, mem in order:
        here = node_xy(rm, node)
        carrier_path = list(costs.path(prev, node))  # GetSmoothedSubRoute
        carrier_path[0] = (problem.start if prev == 0 else carrier_path[0])
        legs = []
        for i in mem:
            task = problem.tasks[i]
            ground = costs.rover_path(i, node)  # GetRoverRoute
            path = w.climb_path(ground, 0.0, task.position[2])
            path[-1] = task.position
            if math.hypot(_ground_len(ground), task.position[2]) > problem.deploy_range:
                raise PlanningError(f"task {task.id}: rover route longer than the deploy range")
            legs.append(RoverLeg(rover=next(rover_ids), task=task.id, path=path))
        stops.append(Stop(position=(here[0], here[1], 0.0), carrier_path=carrier_path, rovers=legs))
        prev = node
    plan = Plan(kind="deploy", planner="lee-graph", start=problem.start, heading=problem.heading, stops=stops)
    plan.roadmap = rm
    return retime(plan, problem.carrier, problem.rover)


def _ground_len(pts: Sequence[Point2]) -> float:
    return sum(math.dist(p, q) for p, q in zip(pts, pts[1:], strict=False))


def plan_lee_graph_screen(problem: DeployProblem) -> Plan:
    """Algorithm 6.3 alone (no search): the teams allocation screens its candidate shares with it
    (``planners.SCREEN_PLANNERS``)."""
    return plan_lee_graph(problem, search=False)
