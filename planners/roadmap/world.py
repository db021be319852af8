"""The obstacle world both roadmap planners share (dissertation ch. 6): the workspace, its roadmap,
the candidate stops of a cluster, and roadmap nodes and paths as ground points."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planners.core.geometry import enclosing_ball
from planners.core.problem import PlanningError, Point2, RoadmapParams, Vec3
from planners.deploy.cluster import ClusterGeometry, max_range_point
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


def node_xy(rm: Roadmap, node: int) -> Point2:
    return (float(rm.xy[node][0]), float(rm.xy[node][1]))


def rover_ground_path(rm: Roadmap, stop: int, target: int, toward: bool) -> list[Point2]:
    """A rover's ground route between its target's node and a stop: a shortest roadmap path from
    the target's node (one shortest-path tree per target serves every stop), shortcut by
    Algorithm 6.2 in the direction it is flown (``toward`` the target: deployment)."""
    nodes = rm.path(target, stop)
    return rm.shortcut(nodes[::-1] if toward else nodes)


def ground_path(pts: Sequence[Point2]) -> list[Vec3]:
    return [(p[0], p[1], 0.0) for p in pts]
