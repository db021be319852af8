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
from planners.core.problem import DeployProblem, PlanningError, Point2, RoadmapParams, Vec3
from planners.core.timing import RANGE_MARGIN, carrier_leg, leg_time, retime
from planners.deploy.lee import ClusterGeometry, max_range_point
from planners.roadmap.graph import Roadmap, Workspace, densify, disc_region, global_prm, local_prm


class GraphWorld:
    """The workspace, the roadmap and the fixed nodes (carrier start = node 0, targets = 1..n).

    ``targets`` are tasks (deployment) or rovers (collection), each with a ground radius ``rho``:
    a node serves target i when the roadmap path between them is at most ``rho[i]`` long.
    """

    def __init__(self, obstacles: Sequence, bounds: tuple[Point2, Point2] | None, start: Vec3,
                 targets: np.ndarray, names: Sequence[str], what: str, rho: np.ndarray, d_edge: float,
                 params: RoadmapParams, seed: int, local: bool = True) -> None:
        self.names, self.what, self.rho, self.d_edge, self.params = list(names), what, rho, d_edge, params
        self.local = local
        self.targets = np.asarray(targets, dtype=float).reshape(-1, 3)
        xy = np.concatenate([[start[:2]], self.targets[:, :2]])
        if bounds is None:  # no workspace given: the points' bounding box grown by the edge length
            pad = max(d_edge, 1.0)
            bounds = ((float(xy[:, 0].min() - pad), float(xy[:, 1].min() - pad)),
                      (float(xy[:, 0].max() + pad), float(xy[:, 1].max() + pad)))
        self.ws = Workspace(obstacles, bounds)
        free, inside = self.ws.points_free(xy), self.ws.inside_bounds(xy)
        for k in range(len(xy)):
            who = "the carrier start" if k == 0 else f"{what} {self.names[k - 1]}"
            if not inside[k]:
                raise PlanningError(f"{who} at ({xy[k][0]:g}, {xy[k][1]:g}) lies outside the bounds; "
                                    "widen the bounds")
            if not free[k]:
                raise PlanningError(f"{who} at ({xy[k][0]:g}, {xy[k][1]:g}) lies inside an obstacle; "
                                    "move it out of the obstacle")
        self.rng = np.random.default_rng(seed)
        self.rm: Roadmap = global_prm(self.ws, xy, d_edge, params, self.rng)  # eq. 6.5–6.6
        densify(self.rm, self.rng, params, range(1, len(xy)))
        d0, _ = self.rm.shortest(0)
        cut = [self.names[k - 1] for k in range(1, len(xy)) if not math.isfinite(d0[k])]
        if cut:
            raise PlanningError(
                f"{what} {', '.join(cut)} cannot be reached from the carrier start on the roadmap: walled "
                "in by obstacles (or behind gaps the roadmap did not sample: raise planner.roadmap.xi1/xi2)")

    def node(self, i: int) -> int:
        """Roadmap node of target i."""
        return i + 1

    def candidates(self, members: Sequence[int], prev: Point2,
                   nxt: Point2 | None) -> tuple[np.ndarray, np.ndarray]:
        """Candidate stop nodes that serve every member, and the (members × nodes) path lengths.

        Candidates: roadmap nodes in the bounding rectangle of the intersection of the members'
        discs (Fig. 6.4), after a local PRM there (eq. 6.7), plus the deterministic open-space
        point of ch. 4 when no obstacle touches the rectangle; only nodes from which every member
        is within its ground radius along the roadmap are kept (Fig. 6.5c).
        """
        mem = list(members)
        rho = self.rho[mem]
        centers = self.targets[mem, :2]
        roi = disc_region(centers, rho)
        if roi is None:
            return np.zeros(0, dtype=np.int64), np.zeros((len(mem), 0))
        lo, hi = roi
        if self.local:
            local_prm(self.rm, self.rng, lo, hi, self.d_edge, self.params)  # eq. 6.7
        if self.ws.rect_free(lo, hi):  # no obstacle around the cluster: ch. 4's point as well
            pts = np.array(self.open_space_points(mem, prev, nxt)).reshape(-1, 2)
            self.rm.add(pts[self.ws.inside_bounds(pts)], self.rm.delta)
        dist = self.rm.distances([self.node(i) for i in mem], limit=float(rho.max()) + 1e-9)
        eps = 1e-9
        xy = self.rm.xy
        in_rect = ((xy[:, 0] >= lo[0] - eps) & (xy[:, 0] <= hi[0] + eps)
                   & (xy[:, 1] >= lo[1] - eps) & (xy[:, 1] <= hi[1] + eps))
        ok = in_rect & np.all(dist <= rho[:, None], axis=0)
        nodes = np.flatnonzero(ok)
        if not len(nodes) and len(mem) == 1:  # a target's own node always serves it
            nodes = np.array([self.node(mem[0])])
        return nodes, dist

    def open_space_points(self, mem: Sequence[int], prev: Point2, nxt: Point2 | None) -> list[Point2]:
        """Ch. 4: the cluster's centre (eq. 3.1 with heights as power weights) and the point at the
        rovers' maximum range toward the carrier's way on (eq. 4.21–4.23)."""
        pts = self.targets[list(mem)]
        rho = self.rho[list(mem)]
        ball = enclosing_ball([(p[0], p[1]) for p in pts], [p[2] ** 2 for p in pts])
        c = (float(ball.center[0]), float(ball.center[1]))
        slack = float(np.min(rho - np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1])))
        if slack < 0:
            return []
        slack = max(slack - 1e-7, 0.0)
        geo = ClusterGeometry(tuple(mem), c, 0.0, slack)
        out = [c]
        if nxt is not None:
            out.append(max_range_point(prev, geo, nxt))
        else:
            dx, dy = prev[0] - c[0], prev[1] - c[1]
            n = math.hypot(dx, dy)
            if n > 1e-12:
                out.append((c[0] + dx / n * min(slack, n), c[1] + dy / n * min(slack, n)))
        return out

    def divide(self, members: Sequence[int], nearest: int) -> list[int]:
        """Algorithm 6.1 (ClusterDivider): drop the task farthest from the nearest one along the
        roadmap, and every task whose path to it is no longer than to the nearest one."""
        mem = list(members)
        near = self.node(nearest)
        d_near = self.rm.shortest(near)[0]
        far = max((i for i in mem if i != nearest), key=lambda i: (d_near[self.node(i)], -i))
        d_far = self.rm.shortest(self.node(far))[0]
        out = []
        for i in mem:
            if i == far:
                continue
            if i != nearest and d_far[self.node(i)] <= d_near[self.node(i)]:
                continue
            out.append(i)
        return out

    def climb_path(self, ground: Sequence[Point2], z_from: float, z_to: float) -> list[Vec3]:
        """A ground polyline with the height changing evenly along it (length √(L² + Δz²))."""
        if len(ground) == 1:
            ground = [ground[0], ground[0]]
        seg = [math.dist(p, q) for p, q in zip(ground, ground[1:], strict=False)]
        total = sum(seg)
        out: list[Vec3] = [(ground[0][0], ground[0][1], z_from)]
        s = 0.0
        for p, ds in zip(ground[1:], seg, strict=True):
            s += ds
            f = s / total if total > 0 else 1.0
            out.append((p[0], p[1], z_from + (z_to - z_from) * f))
        return out

    def drawing(self) -> Roadmap:
        return self.rm


def _xy(rm: Roadmap, node: int) -> Point2:
    return (float(rm.xy[node][0]), float(rm.xy[node][1]))


def _ground_path(pts: Sequence[Point2]) -> list[Vec3]:
    return [(p[0], p[1], 0.0) for p in pts]


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
        path = _ground_path(self.w.rm.smoothed_path(self.prev, node))  # Algorithm 6.2
        dt, self.heading = carrier_leg(path, self.heading, self.p.carrier)
        self.t += dt + self.p.carrier.deploy_stop_time
        self.worst = max(self.worst, self.t + self.rover_time(mem, dist, node))
        self.stops.append((node, mem))
        self.prev = node

    def exact_single(self, node: int, mem: list[int], dist: np.ndarray) -> float:
        """Makespan if the carrier's last stop is ``node`` serving ``mem`` (eq. 6.3)."""
        path = _ground_path(self.w.rm.smoothed_path(self.prev, node))
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
        prev_xy = _xy(self.w.rm, self.prev)
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
        prev_xy = _xy(self.w.rm, self.prev)
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


def plan_lee_graph(problem: DeployProblem, local_prm: bool = True) -> Plan:
    """Algorithm 6.3 on a probabilistic roadmap, planner name ``lee-graph``."""
    t0 = time.perf_counter()
    if len(problem.rover_ids()) < len(problem.tasks):
        raise PlanningError(f"{len(problem.tasks)} tasks need as many rovers, only "
                            f"{len(problem.rover_ids())} on the carrier")
    if not problem.tasks:
        return Plan(kind="deploy", planner="lee-graph", start=problem.start, heading=problem.heading,
                    stops=[])
    dep = _Deploy(problem, local_prm)
    order = dep.run()
    plan = build_graph_plan(problem, dep.w, order)
    plan.compute_ms = (time.perf_counter() - t0) * 1e3
    return plan


def build_graph_plan(problem: DeployProblem, w: GraphWorld,
                     order: Sequence[tuple[int, Sequence[int]]]) -> Plan:
    """Carrier sub-routes and rover routes on the final roadmap, shortcut, and timed (eq. 6.3)."""
    rm = w.rm
    rover_ids = iter(problem.rover_ids())
    stops: list[Stop] = []
    prev = 0
    for node, mem in order:
        here = _xy(rm, node)
        carrier_path = _ground_path(rm.smoothed_path(prev, node))  # GetSmoothedSubRoute
        carrier_path[0] = (problem.start if prev == 0 else carrier_path[0])
        legs = []
        for i in mem:
            task = problem.tasks[i]
            ground = rm.smoothed_path(node, w.node(i))  # GetRoverRoute
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
