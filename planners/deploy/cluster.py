"""Deployment clusters (dissertation ch. 4.4): where a cluster can be served from, and the
per-problem caches the path builder reads."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planners.core.geometry import enclosing_circle
from planners.core.native import kernels
from planners.core.problem import DeployProblem, PlanningError, Point2, Vec3
from planners.core.timing import RANGE_MARGIN


@dataclass(frozen=True)
class ClusterGeometry:
    """Where a cluster can be served from.

    ``center`` is the ground point whose farthest task is nearest (a power-weighted enclosing
    circle, see planners.core.geometry), ``reach`` that farthest 3D distance, ``slack`` the radius
    of the disc around ``center`` from every point of which all tasks are within d_deploy
    (the disc of eq. 4.23: (Δd)² + z² = (d_deploy − π)² in the chapter's sphere form).
    """

    members: tuple[int, ...]
    center: Point2
    reach: float
    slack: float


class DeployInstance:
    """Per-problem caches: task coordinates and cluster geometry by membership."""

    def __init__(self, problem: DeployProblem) -> None:
        self.problem = problem
        self.pts: list[Vec3] = [t.position for t in problem.tasks]
        self.xyz = np.array(self.pts, dtype=float).reshape(-1, 3)  # the same, for numpy scoring
        self.range = problem.deploy_range
        self.d = max(problem.deploy_range - RANGE_MARGIN, 0.0)  # planned flights stay inside this
        self._geo: dict[tuple[int, ...], ClusterGeometry] = {}
        # per task: the radius of the ground disc from which it is within d_deploy
        self._disc = [math.sqrt(max(self.d**2 - p[2] ** 2, 0.0)) for p in self.pts]
        self._rows = [(p[0], p[1], p[2] * p[2]) for p in self.pts]  # x, y, z² of every task, for reach_from
        for i, p in enumerate(self.pts):
            if p[2] > self.range or p[2] < 0:
                raise PlanningError(
                    f"task {problem.tasks[i].id} at height {p[2]:g} m cannot be reached with a "
                    f"deploy range of {problem.deploy_range:g} m")

    def geometry(self, members: Sequence[int]) -> ClusterGeometry:
        key = tuple(sorted(members))
        g = self._geo.get(key)
        if g is None:
            pts = [self.pts[i] for i in key]
            xs, ys = [p[0] for p in pts], [p[1] for p in pts]
            cx, cy, radius = enclosing_circle(xs, ys, [p[2] ** 2 for p in pts])
            disc = self._disc
            slack = max(0.0, min([disc[i] - math.hypot(x - cx, y - cy)
                                  for i, x, y in zip(key, xs, ys, strict=True)]))
            g = ClusterGeometry(key, (cx, cy), radius, slack)
            self._geo[key] = g
        return g

    def fits_quick(self, members: Sequence[int]) -> bool:
        """``fits`` behind a cheaper test: the first and last tasks must be within 2·d_deploy."""
        return math.dist(self.pts[members[0]], self.pts[members[-1]]) <= 2 * self.range and self.fits(members)

    def fits(self, members: Sequence[int]) -> bool:
        """Can one stop serve every task of the cluster within d_deploy (Algorithm 4.1's test)?"""
        if len(members) > 3:  # cheap necessary test before the enclosing circle: two tasks farther
            xs = [self.pts[i][0] for i in members]  # apart than 2·d_deploy never share a stop
            ys = [self.pts[i][1] for i in members]
            if max(xs) - min(xs) > 2 * self.range or max(ys) - min(ys) > 2 * self.range:
                return False
        return self.geometry(members).reach <= self.range

    def reach_from(self, p: Point2, members: Sequence[int]) -> float:
        """Longest rover flight from ground point ``p`` to the cluster's tasks (eq. 4.5 numerator)."""
        return _reach_of(self._rows, members, p[0], p[1])

    def feasible_from(self, a: Point2, b: Point2, members: Sequence[int]) -> float:
        """Smallest s in [0, 1] such that a + s·(b − a) serves every task (b must serve them)."""
        s_lo = 0.0
        dx, dy = b[0] - a[0], b[1] - a[1]
        qa = dx * dx + dy * dy
        for i in members:
            x, y, z = self.pts[i]
            r2 = self.d**2 - z * z
            if 0.0 > r2:  # (max(r2, 0.0), written out: the same element as the builtin)
                r2 = 0.0
            ex, ey = a[0] - x, a[1] - y
            qc = ex * ex + ey * ey - r2
            if qc <= 0:
                continue
            if qa == 0:
                return 1.0
            qb = 2 * (dx * ex + dy * ey)
            disc = qb * qb - 4 * qa * qc
            s1 = (-qb - math.sqrt(0.0 if 0.0 > disc else disc)) / (2 * qa)
            if s1 > s_lo:
                s_lo = s1
        return min(max(s_lo, 0.0), 1.0)


def lerp(a: Point2, b: Point2, s: float) -> Point2:
    return (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]))


def max_range_point(prev: Point2, geo: ClusterGeometry, nxt: Point2) -> Point2:
    """Deployment point of an early cluster (eq. 4.21–4.23): at the rovers' maximum range,
    moved from the cluster centre toward the carrier's line to the next cluster.

    The point is the one of the disc (centre, slack) nearest the line prev → next: on the
    perpendicular through the centre (4.22) at Δd = slack (4.23), or the foot of the
    perpendicular when the line already crosses the disc.
    """
    cx, cy = geo.center
    dx, dy = nxt[0] - prev[0], nxt[1] - prev[1]
    n2 = dx * dx + dy * dy
    if n2 < 1e-18:
        fx, fy = prev
    else:
        s = ((cx - prev[0]) * dx + (cy - prev[1]) * dy) / n2
        fx, fy = prev[0] + s * dx, prev[1] + s * dy  # foot of the perpendicular (4.21 ∩ 4.22)
    ox, oy = fx - cx, fy - cy
    off = math.hypot(ox, oy)
    step = max(geo.slack, 0.0)
    if off <= step:
        return (fx, fy)
    return (cx + ox / off * step, cy + oy / off * step)


def max_range_points(px: np.ndarray, py: np.ndarray, cx: np.ndarray, cy: np.ndarray, slack: np.ndarray,
                     nx: np.ndarray, ny: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``max_range_point`` of every row (numpy, broadcast; the same arithmetic in the same order):
    prev = (px, py), the disc (cx, cy, slack ≥ 0), next = (nx, ny)."""
    dx, dy = nx - px, ny - py
    n2 = dx * dx + dy * dy
    s = np.where(n2 < 1e-18, 0.0, ((cx - px) * dx + (cy - py) * dy) / np.where(n2 < 1e-18, 1.0, n2))
    fx, fy = px + s * dx, py + s * dy
    ox, oy = fx - cx, fy - cy
    off = np.hypot(ox, oy)
    inside = off <= slack
    off = np.where(inside, 1.0, off)
    return np.where(inside, fx, cx + ox / off * slack), np.where(inside, fy, cy + oy / off * slack)


def reach_of(rows: Sequence[tuple[float, float, float]], members: Sequence[int], x: float, y: float) -> float:
    """Longest flight from (x, y) on the ground to the rows (x, y, z²) of ``members``."""
    worst = 0.0
    for i in members:
        qx, qy, z2 = rows[i]
        d2 = (qx - x) ** 2 + (qy - y) ** 2 + z2
        if d2 > worst:
            worst = d2
    return math.sqrt(worst)


_reach_of = reach_of if kernels is None else kernels.reach_of  # the compiled twin: the same float
