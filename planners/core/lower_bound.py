"""Lower bounds on mission makespans."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planners.core.approach import lifted_tasks
from planners.core.problem import DeployProblem, Motion
from planners.core.timing import leg_time

_GRID = 48


def deploy_lower_bound(problem: DeployProblem) -> float:
    """A makespan no deployment plan can beat: the larger of two bounds.

    1. Per task (``_task_bound``): the earliest any rover can reach one task.
    2. Stops (``_stops_bound``): the carrier's unloading and driving that any plan needs.
    """
    if problem.takeoff_height > 0.0:  # flights start above the stop (planners.core.approach)
        problem = lifted_tasks(problem)
    return max(_task_bound(problem), _stops_bound(problem))


def _stops_bound(problem: DeployProblem) -> float:
    """Argument. A ground point within d_deploy of two tasks exists only if their horizontal
    distance is at most r_a + r_b, with r = sqrt(d_deploy² − z²) a task's horizontal reach. So a
    set of tasks pairwise farther apart than that (chosen greedily) needs one stop each: at least
    K stops, each unloading once. The stops p_a serving those tasks satisfy
    |p_a − p_b| ≥ |t_a − t_b| − r_a − r_b and |start − p_a| ≥ |start − t_a| − r_a, and the
    carrier's path from the start through them contains a spanning tree of them, so its length
    is at least the minimum spanning tree W under those reduced distances. Driving a length W
    takes ≥ leg_time(W) (see ``_task_bound``). The last unload ends no earlier than
    leg_time(W) + K · unload_time, and the makespan is at least that.
    """
    if not problem.tasks:
        return 0.0
    xy = np.array([t.position[:2] for t in problem.tasks], dtype=float)
    z = np.array([t.position[2] for t in problem.tasks], dtype=float)
    reach = np.sqrt(np.maximum(problem.deploy_range**2 - z**2, 0.0))
    return separated_stops_bound(xy, reach, problem.start[:2], problem.carrier.motion,
                                 problem.carrier.deploy_stop_time)


def separated_stops_bound(xy: np.ndarray, reach: np.ndarray, start: Sequence[float], carrier: Motion,
                          per_stop: float) -> float:
    """leg_time(W) + K · per_stop for the discs (centre xy, radius reach) that each need a stop of
    their own: K discs chosen greedily (nearest the start first) pairwise disjoint, W the minimum
    spanning tree over the start and those discs with gap distances (see ``_stops_bound``)."""
    origin = np.asarray(start, dtype=float)
    order = np.argsort(np.linalg.norm(xy - origin, axis=1))
    chosen: list[int] = []
    for i in order:
        if all(np.linalg.norm(xy[i] - xy[j]) > reach[i] + reach[j] for j in chosen):
            chosen.append(int(i))
    pts, r = xy[chosen], reach[chosen]
    k = len(chosen)
    w = np.zeros((k + 1, k + 1))
    w[0, 1:] = np.maximum(np.linalg.norm(pts - origin, axis=1) - r, 0.0)
    w[1:, 1:] = np.maximum(np.linalg.norm(pts[:, None] - pts[None], axis=2) - r[:, None] - r[None, :], 0.0)
    w = np.maximum(w, w.T)
    return leg_time(mst_length(w), carrier) + k * per_stop


def _task_bound(problem: DeployProblem) -> float:
    """Argument. Take any feasible plan and any task i at horizontal distance L from the carrier's
    start and height z. Its rover leaves the carrier at some ground point p, after the carrier
    has driven a path of length ≥ D = |p − start| and unloaded at least once. The carrier's
    travel time over a path of length ≥ D is ≥ leg_time(D): a path is a chain of rest-to-rest
    legs, the leg time is increasing and concave with leg_time(0) = 0, hence subadditive, so
    splitting the distance into legs never beats one leg; turns and extra stops only add. The
    rover then flies ≥ g(D) = sqrt((L − D)² + z²) (triangle inequality), which must be within
    d_deploy, taking ≥ leg_time(g(D)). So task i is reached no earlier than

        LB_i = unload_time + min over feasible D of [leg_c(D) + leg_r(g(D))].

    The minimum is bounded from below on a grid D_0 < … < D_m of the feasible interval: on
    [D_j, D_j+1] the first term is ≥ leg_c(D_j) and the second ≥ leg_r(g(D_j+1)) (both
    monotone), so the bound never exceeds the true minimum. LB = max_i LB_i.
    """
    c, r = problem.carrier, problem.rover
    best = 0.0
    for t in problem.tasks:
        x, y, z = t.position
        L = math.hypot(x - problem.start[0], y - problem.start[1])
        reach = math.sqrt(max(problem.deploy_range**2 - z * z, 0.0))
        lo = max(0.0, L - reach)
        hi = L
        grid = [lo + (hi - lo) * j / _GRID for j in range(_GRID + 1)]
        car = [leg_time(d, c.motion) for d in grid]
        rov = [leg_time(math.sqrt((L - d) ** 2 + z * z), r) for d in grid]
        if hi - lo <= 0.0:
            bound = car[0] + rov[0]
        else:
            bound = min(car[j] + rov[j + 1] for j in range(_GRID))
        best = max(best, c.deploy_stop_time + bound)
    return best


def mst_length(w: np.ndarray) -> float:
    """Total weight of a minimum spanning tree of a complete graph (Prim, dense)."""
    n = len(w)
    if n <= 1:
        return 0.0
    in_tree = np.zeros(n, dtype=bool)
    in_tree[0] = True
    best = w[0].copy()
    total = 0.0
    for _ in range(n - 1):
        cand = np.where(in_tree, np.inf, best)
        j = int(np.argmin(cand))
        total += float(cand[j])
        in_tree[j] = True
        best = np.minimum(best, w[j])
    return total
