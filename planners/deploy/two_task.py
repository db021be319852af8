"""Optimal deployment for two tasks (dissertation ch. 4.3, eq. 4.10–4.17), in 2D and 3D.

Three ways to deploy two rovers (Fig. 4.1): I, both fly from the carrier's start; II, the
carrier drives to one point and unloads both; III, the carrier unloads the first rover on its
way and the second under the second task. Case III's first stop lies on the segment from the
carrier to the first task: without delays it is where that segment meets the circle of
Apollonius of the two tasks (eq. 4.13); the carrier's rotation, acceleration and unloading
move it toward the carrier by Δd (eq. 4.14/4.17), and d_deploy clamps it. The fastest case wins.

The chapter calls this optimal; it is optimal among stops on those segments. With rotation and
acceleration a first stop off the segment can be faster still, which ``lee``'s final polish
finds (Table 4.2: 10.65 s against this construction's 11.06 s).
"""

from __future__ import annotations

import math
import time

from planners.core.geometry import enclosing_ball, find_root, minimize_1d
from planners.core.plan import Plan
from planners.core.problem import DeployProblem, PlanningError, refuse_obstacles
from planners.core.timing import RANGE_MARGIN, carrier_hop, leg_time
from planners.deploy.build import build_plan

Point2 = tuple[float, float]


def apollonius_circle(g1: Point2, g2: Point2, v_c: float, v_r: float) -> tuple[Point2, float]:
    """Eq. 4.13: points P with |P − g1| / v_r = |P − g2| / v_c (rover to g1 while carrier to g2)."""
    if v_c <= v_r:
        raise ValueError("the circle of Apollonius needs a carrier faster than the rovers")
    k = v_c**2 - v_r**2
    center = ((v_c**2 * g1[0] - v_r**2 * g2[0]) / k, (v_c**2 * g1[1] - v_r**2 * g2[1]) / k)
    return center, v_c * v_r * math.dist(g1, g2) / k


def apollonius_point(start: Point2, g1: Point2, g2: Point2, v_c: float, v_r: float) -> float | None:
    """Eq. 4.10 ∩ 4.13: parameter s ∈ [0, 1] on start → g1 where the segment meets the circle."""
    (cx, cy), rad = apollonius_circle(g1, g2, v_c, v_r)
    dx, dy = g1[0] - start[0], g1[1] - start[1]
    ex, ey = start[0] - cx, start[1] - cy
    a, b, c = dx * dx + dy * dy, 2 * (dx * ex + dy * ey), ex * ex + ey * ey - rad * rad
    disc = b * b - 4 * a * c
    if a == 0 or disc < 0:
        return None
    roots = [(-b - math.sqrt(disc)) / (2 * a), (-b + math.sqrt(disc)) / (2 * a)]
    inside = [s for s in roots if 0.0 <= s <= 1.0]
    return min(inside) if inside else None


def plan_two_tasks(problem: DeployProblem) -> Plan:
    """The optimal deployment of exactly two tasks (ch. 4.3); planner name ``two-task``."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "two-task")
    if len(problem.tasks) != 2:
        raise PlanningError("the two-task deployment needs exactly two tasks")
    d = problem.deploy_range - RANGE_MARGIN
    pts = [t.position for t in problem.tasks]
    start: Point2 = (problem.start[0], problem.start[1])
    c, r, unload = problem.carrier, problem.rover, problem.carrier.deploy_stop_time
    candidates: list[tuple[list[list[int]], list[Point2]]] = []

    def rover_time(p: Point2, i: int) -> float:
        return leg_time(math.dist((*p, 0.0), pts[i]), r)

    # Case I: both rovers fly from the start.
    if all(math.dist((*start, 0.0), q) <= d for q in pts):
        candidates.append(([[0, 1]], [start]))
    # Case II: one stop for both — the ground point whose farther task is nearest.
    ball = enclosing_ball([q[:2] for q in pts], [q[2] ** 2 for q in pts])
    if ball.radius <= problem.deploy_range:
        candidates.append(([[0, 1]], [(ball.center[0], ball.center[1])]))
    # Case III, both orders: first stop on start → first task, second under the second task.
    for first, second in ((0, 1), (1, 0)):
        g1, g2 = pts[first][:2], pts[second][:2]
        reach = math.sqrt(max(d * d - pts[first][2] ** 2, 0.0))
        length = math.dist(start, g1)
        s_lo = max(0.0, 1.0 - reach / length) if length > 0 else 1.0

        def at(s: float, g1: Point2 = g1) -> Point2:
            return (start[0] + s * (g1[0] - start[0]), start[1] + s * (g1[1] - start[1]))

        def balance(s: float, first: int = first, second: int = second, g2: Point2 = g2) -> float:
            # Eq. 4.14/4.17: rover 1's flight minus (carrier to q_ω2 + unload + rover 2's climb).
            p = at(s)
            _, h = carrier_hop(start, p, problem.heading, c)
            hop, _ = carrier_hop(p, g2, h, c)
            return rover_time(p, first) - (hop + unload + rover_time(g2, second))

        reach2 = math.sqrt(max(d * d - pts[second][2] ** 2, 0.0))

        def second_stop(p: Point2, u: float, g2: Point2 = g2) -> Point2:
            return (p[0] + u * (g2[0] - p[0]), p[1] + u * (g2[1] - p[1]))

        def finish(s: float, u: float, first: int = first, second: int = second) -> float:
            p = at(s)
            q = second_stop(p, u)
            t1, h = carrier_hop(start, p, problem.heading, c)
            hop, _ = carrier_hop(p, q, h, c)
            return t1 + unload + max(rover_time(p, first), hop + unload + rover_time(q, second))

        def best_u(s: float, g2: Point2 = g2, reach2: float = reach2) -> float:
            # q_ω2 may stop short of the second task when its rover outruns the carrier's braking.
            span = math.dist(at(s), g2)
            u_lo = max(0.0, 1.0 - reach2 / span) if span > 0 else 1.0
            return minimize_1d(lambda u: finish(s, u), u_lo, 1.0, samples=8, tol=1e-9)[0]

        def makespan(s: float) -> float:
            return finish(s, best_u(s))

        options = [s_lo, 1.0]
        faster = c.max_speed > r.max_speed
        s_old = apollonius_point(start, g1, g2, c.max_speed, r.max_speed) if faster else None
        if s_old is not None:
            options.append(min(max(s_old, s_lo), 1.0))
        if balance(s_lo) * balance(1.0) < 0:
            options.append(find_root(balance, s_lo, 1.0, xtol=1e-12))  # Δd of eq. 4.14 / 4.17
        options.append(minimize_1d(makespan, s_lo, 1.0, tol=1e-9)[0])  # the exact time model's optimum
        s_best = min(options, key=makespan)
        p_best = at(s_best)
        candidates.append(([[first], [second]], [p_best, second_stop(p_best, best_u(s_best))]))

    plans = [build_plan(problem, "two-task", cl, pos) for cl, pos in candidates]
    best = min(plans, key=lambda p: p.makespan)
    best.compute_ms = (time.perf_counter() - t0) * 1e3
    return best
