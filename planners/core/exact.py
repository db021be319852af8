"""An exact reference for tiny deployment and collection problems (n ≤ 5), for tests and benchmarks.

Every ordered partition of the tasks (rovers) into stops is tried; for each, the stops' ground
positions are placed by constrained optimisation on the exact time model (``planners.core.timing``):
SLSQP on the epigraph form (minimise T with T ≥ every rover's arrival, resp. η_k ≥ η_{k−1} + hop
and η_k ≥ a rover's landing, and every flight within its range) from several starts, then a
compass search on the exact, non-smooth makespan that only keeps feasible improvements. It is a
reference, not a proof: the placement of one ordered partition is a non-convex program (turn
times, acceleration) solved by multi-start local search.

Not a planner: it is exponential in n (541 ordered partitions at n = 5) and imports SciPy. Nothing
in ``planners`` imports it; tests and ``bench/optimality.py`` do.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from planners.core.geometry import enclosing_ball
from planners.core.partitions import ordered_partitions
from planners.core.problem import CollectProblem, DeployProblem
from planners.core.timing import RANGE_MARGIN, carrier_hop, leg_time

Point2 = tuple[float, float]
_SLSQP_SHRINK = 1e-4  # m: SLSQP works this far inside each reach disc (its constraints are soft)


@dataclass
class ExactResult:
    makespan: float
    clusters: list[list[int]]
    positions: list[Point2]


class _Model:
    """Items (tasks or rovers) with ground points g_i, heights z_i and ground reach radii r_i."""

    def __init__(self, problem: DeployProblem | CollectProblem) -> None:
        self.deploy = isinstance(problem, DeployProblem)
        c = problem.carrier
        self.carrier, self.rover = c, problem.rover
        self.pause = c.deploy_stop_time if self.deploy else c.collect_stop_time
        self.start: Point2 = (problem.start[0], problem.start[1])
        self.heading = problem.heading
        if isinstance(problem, DeployProblem):
            pts = [t.position for t in problem.tasks]
            ranges = [problem.deploy_range] * len(pts)
        else:
            pts = [r.position for r in problem.rovers]
            ranges = [r.range for r in problem.rovers]
        self.g = [(p[0], p[1]) for p in pts]
        self.z2 = [p[2] * p[2] for p in pts]
        self.lim = [max(r - RANGE_MARGIN, 0.0) for r in ranges]  # 3D flight limit
        self.r = [math.sqrt(max(L * L - z2, 0.0)) for L, z2 in zip(self.lim, self.z2, strict=True)]

    def flight(self, p: Point2, i: int) -> float:
        g = self.g[i]
        return math.sqrt((p[0] - g[0]) ** 2 + (p[1] - g[1]) ** 2 + self.z2[i])

    def feasible(self, clusters: Sequence[Sequence[int]], positions: Sequence[Point2]) -> bool:
        return all(self.flight(p, i) <= self.lim[i] + 1e-9
                   for c, p in zip(clusters, positions, strict=True) for i in c)

    def makespan(self, clusters: Sequence[Sequence[int]], positions: Sequence[Point2]) -> float:
        """The time model (docs/time-model.md) for straight legs (as ``timing.deploy/collect_schedule``)."""
        prev, h, t, worst = self.start, self.heading, 0.0, 0.0
        for c, p in zip(clusters, positions, strict=True):
            dt, h = carrier_hop(prev, p, h, self.carrier)
            flights = [leg_time(self.flight(p, i), self.rover) for i in c]
            if self.deploy:
                t += dt + self.pause
                worst = max(worst, t + max(flights))
            else:
                t = max(t + dt, *flights) + self.pause
            prev = p
        return worst if self.deploy else t

    def center(self, c: Sequence[int]) -> Point2 | None:
        """A point of the cluster's reach region (its power centre), None when the discs miss."""
        big = max(self.r[i] ** 2 for i in c)
        ball = enclosing_ball([self.g[i] for i in c], [big - self.r[i] ** 2 for i in c])
        if ball.radius ** 2 > big + 1e-9:
            return None
        return (ball.center[0], ball.center[1])

    def project(self, p: Point2, c: Sequence[int]) -> Point2:
        """A point of the region near ``p`` (alternating projections onto the discs)."""
        x, y = p
        for _ in range(60):
            moved = False
            for i in c:
                gx, gy = self.g[i]
                rho = max(self.r[i] - 2 * _SLSQP_SHRINK, 0.0)
                d = math.hypot(x - gx, y - gy)
                if d > rho:
                    x, y = (gx, gy) if d == 0 else (gx + (x - gx) * rho / d, gy + (y - gy) * rho / d)
                    moved = True
            if not moved:
                break
        return (x, y)

    # -- placement of one ordered partition ---------------------------------------------------

    def _slsqp(self, clusters: list[list[int]], x0: list[Point2]) -> list[Point2]:
        k = len(clusters)
        car, rov, pause = self.carrier, self.rover, self.pause
        pairs = [(j, i) for j, c in enumerate(clusters) for i in c]
        gx = np.array([self.g[i][0] for _, i in pairs])
        gy = np.array([self.g[i][1] for _, i in pairs])
        rr = np.array([max(self.r[i] - _SLSQP_SHRINK, 0.0) ** 2 for _, i in pairs])
        js = np.array([j for j, _ in pairs])

        def hops(z: np.ndarray) -> list[float]:
            prev, h, out = self.start, self.heading, []
            for j in range(k):
                p = (z[2 * j], z[2 * j + 1])
                dt, h = carrier_hop(prev, p, h, car)
                out.append(dt)
                prev = p
            return out

        def arrivals(z: np.ndarray) -> list[float]:
            return [leg_time(self.flight((z[2 * j], z[2 * j + 1]), i), rov) for j, i in pairs]

        def reach(z: np.ndarray) -> np.ndarray:
            xs, ys = z[0:2 * k:2][js], z[1:2 * k:2][js]
            return rr - (xs - gx) ** 2 - (ys - gy) ** 2

        rows = np.arange(len(pairs))

        def reach_jac(z: np.ndarray) -> np.ndarray:
            jac = np.zeros((len(pairs), len(z)))
            jac[rows, 2 * js] = -2 * (z[0:2 * k:2][js] - gx)
            jac[rows, 2 * js + 1] = -2 * (z[1:2 * k:2][js] - gy)
            return jac

        if self.deploy:  # variables: positions, T
            def timing(z: np.ndarray) -> np.ndarray:
                t = np.cumsum(hops(z)) + pause * np.arange(1, k + 1)
                return z[-1] - (t[js] + np.array(arrivals(z)))
            z0 = [c for p in x0 for c in p] + [self.makespan(clusters, x0)]
        else:  # variables: positions, η_1..η_k
            def timing(z: np.ndarray) -> np.ndarray:
                eta = z[2 * k:]
                chain = eta - np.concatenate(([0.0], eta[:-1])) - np.array(hops(z)) - pause
                land = eta[js] - np.array(arrivals(z)) - pause
                return np.concatenate((chain, land))
            etas, prev, h, t = [], self.start, self.heading, 0.0
            for c, p in zip(clusters, x0, strict=True):
                dt, h = carrier_hop(prev, p, h, car)
                t = max(t + dt, *(leg_time(self.flight(p, i), rov) for i in c)) + pause
                etas.append(t)
                prev = p
            z0 = [c for p in x0 for c in p] + etas
        try:
            z0a = np.array(z0, dtype=float)
            grad = np.zeros(len(z0a))
            grad[-1] = 1.0
            res = minimize(lambda z: z[-1], z0a, jac=lambda z: grad, method="SLSQP",
                           constraints=[{"type": "ineq", "fun": timing},
                                        {"type": "ineq", "fun": reach, "jac": reach_jac}],
                           options={"maxiter": 40, "ftol": 1e-9})
            z = res.x
        except (ValueError, ArithmeticError):
            return x0
        out = [self.project((float(z[2 * j]), float(z[2 * j + 1])), c) for j, c in enumerate(clusters)]
        return out

    def _compass(self, clusters: list[list[int]], pos: list[Point2],
                 step: float) -> tuple[float, list[Point2]]:
        dirs = [(math.cos(a * math.pi / 4), math.sin(a * math.pi / 4)) for a in range(8)]
        pos = list(pos)
        best = self.makespan(clusters, pos)
        while step > 1e-4:
            improved = False
            for j, c in enumerate(clusters):
                for dx, dy in dirs:
                    q = (pos[j][0] + step * dx, pos[j][1] + step * dy)
                    if any(self.flight(q, i) > self.lim[i] for i in c):
                        continue
                    trial = pos[:j] + [q] + pos[j + 1:]
                    t = self.makespan(clusters, trial)
                    if t < best - 1e-12:
                        best, pos, improved = t, trial, True
                        break
            if not improved:
                step /= 2
        return best, pos

    def starts(self, clusters: list[list[int]], centers: list[Point2], rng: random.Random,
               extra: int) -> list[list[Point2]]:
        out = [list(centers)]
        prev, greedy = self.start, []
        for c in clusters:  # each stop at the point of its region nearest the carrier
            prev = self.project(prev, c)
            greedy.append(prev)
        out.append(greedy)
        for _ in range(extra):
            out.append([self.project((p[0] + rng.gauss(0, 1) * self.r[c[0]],
                                      p[1] + rng.gauss(0, 1) * self.r[c[0]]), c)
                        for p, c in zip(centers, clusters, strict=True)])
        return out

    def place(self, clusters: list[list[int]], starts: list[list[Point2]],
              slsqp: bool = True) -> tuple[float, list[Point2]]:
        best, best_pos = math.inf, starts[0]
        scale = max(max(self.r[i] for i in c) for c in clusters) / 4 + 0.05
        for x0 in starts:
            for cand in ((self._slsqp(clusters, x0), x0) if slsqp else (x0,)):
                if not self.feasible(clusters, cand):
                    continue
                t, pos = self._compass(clusters, cand, scale)
                if t < best:
                    best, best_pos = t, pos
        return best, best_pos


def place_partition(problem: DeployProblem | CollectProblem, clusters: Sequence[Sequence[int]],
                    positions: Sequence[Point2]) -> float:
    """The makespan of one ordered partition placed from ``positions`` (SLSQP + compass search,
    as ``exact_plan`` places its best partitions); inf when the start is not feasible."""
    m = _Model(problem)
    t, _ = m.place([list(c) for c in clusters], [list(positions)])
    return t


def exact_plan(problem: DeployProblem | CollectProblem, seed: int = 0, starts: int = 2,
               keep: float = 0.05, hint: tuple[Sequence[Sequence[int]], Sequence[Point2]] | None = None
               ) -> ExactResult:
    """The best plan over every ordered partition (n ≤ 5 or so).

    Every partition is placed from the power centres and the greedy start (compass search);
    the partitions within ``keep`` (relative) of the best are placed again by SLSQP + compass
    search from their best point and ``starts`` more random starts. ``hint`` (clusters,
    positions), e.g. a planner's plan, is one more start for its partition, so the reference is
    never worse than that plan.
    """
    m = _Model(problem)
    n = len(m.g)
    if n == 0:
        return ExactResult(0.0, [], [])
    rng = random.Random(seed)
    centers: dict[tuple[int, ...], Point2 | None] = {}

    def center(c: list[int]) -> Point2 | None:
        key = tuple(sorted(c))
        if key not in centers:
            centers[key] = m.center(key)
        return centers[key]

    scored: list[tuple[float, list[list[int]], list[Point2], list[Point2]]] = []
    for clusters in ordered_partitions(n):
        cs = [center(c) for c in clusters]
        if any(c is None for c in cs):
            continue
        cpts = [c for c in cs if c is not None]
        t, pos = m.place(clusters, m.starts(clusters, cpts, rng, 0), slsqp=False)
        scored.append((t, clusters, pos, cpts))
    if hint is not None:
        hc = [sorted(c) for c in hint[0]]
        for idx, (t, clusters, _pos, cpts) in enumerate(scored):
            if [sorted(c) for c in clusters] == hc:
                t2, pos2 = m.place(clusters, [list(hint[1])])
                if t2 < t:
                    scored[idx] = (t2, clusters, pos2, cpts)
    if not scored:
        raise ValueError("no ordered partition is feasible")
    best = min(s[0] for s in scored)
    for idx, (t, clusters, pos, cpts) in enumerate(scored):
        if t <= best * (1 + keep) and starts > 0:
            t2, pos2 = m.place(clusters, [pos, *m.starts(clusters, cpts, rng, starts)[2:]])
            if t2 < t:
                scored[idx] = (t2, clusters, pos2, cpts)
    t, clusters, pos, _ = min(scored, key=lambda s: s[0])
    return ExactResult(t, clusters, pos)
