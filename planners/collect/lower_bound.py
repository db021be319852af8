"""A lower bound on the collection makespan (eq. 5.2) that no feasible plan can beat."""

from __future__ import annotations

import math

import numpy as np

from planners.collect.instance import CollectInstance
from planners.core.approach import lifted
from planners.core.lower_bound import separated_stops_bound
from planners.core.problem import CollectProblem
from planners.core.timing import leg_time

_BISECT = 60


def collect_lower_bound(problem: CollectProblem) -> float:
    """The larger of two bounds (both ≤ the makespan of every feasible plan):

    1. per rover (``_rover_bound``): the earliest the carrier and that rover can meet, plus loading;
    2. stops (``_stops_bound``): the loads and driving any plan needs.

    Reach radii are the exact ones, sqrt(range² − z²), not the planners' RANGE_MARGIN-reduced ones,
    so the bound also holds for plans that use the full range.
    """
    if problem.approach_height > 0.0:  # flights end above the stop (planners.core.approach)
        problem = lifted(problem)
    CollectInstance(problem)  # the same validation as the planners: infeasible rovers by id
    if not problem.rovers:
        return 0.0
    return max(_rover_bound(problem), _stops_bound(problem))


def _reach(problem: CollectProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    xy = np.array([r.position[:2] for r in problem.rovers], dtype=float)
    z = np.array([r.position[2] for r in problem.rovers], dtype=float)
    rng = np.array([r.range for r in problem.rovers], dtype=float)
    return xy, z, np.sqrt(np.maximum(rng * rng - z * z, 0.0))


def _rover_bound(problem: CollectProblem) -> float:
    """Argument. In any feasible plan rover i (ground position g, height z, reach ρ) is loaded at a
    stop m with |m − g| ≤ ρ, at a time ≥ max(carrier reaches m, rover lands at m) + load_time
    (eq. 5.2), and the makespan is at least that departure. The carrier's time to reach m is at
    least leg_c(D) with D = |m − start|: its path is ≥ D long, made of rest-to-rest legs whose time
    leg_c is increasing, concave and zero at zero, hence subadditive, so no split into legs beats
    one leg; rotations, waits and earlier loads only add. The rover flies straight (it may not fly
    a shorter path), so it needs leg_r(sqrt(|m − g|² + z²)) ≥ leg_r(sqrt((L − D)² + z²)) where
    L = |g − start| (triangle inequality: |m − g| ≥ |L − D|). Over every feasible D (D ≥ L − ρ)

        LB_i = load_time + min_D max(leg_c(D), leg_r(sqrt((L − D)² + z²))).

    For D ≥ L the first term alone is ≥ leg_c(L), so D ∈ [max(0, L − ρ), L] suffices, where the
    first term increases and the second decreases. Bisection brackets their crossing in
    [D_lo, D_hi] with the carrier slower at D_hi and the rover slower at D_lo; every D then has
    max(...) ≥ max(leg_c(D_lo), leg_r(D_hi)) (left of D_lo the rover term is ≥ its value at D_lo,
    which exceeds leg_c(D_lo); right of D_hi the carrier term is ≥ leg_c(D_hi) ≥ leg_r(D_hi);
    inside, each term is bounded by its value at the far end), so that value is a valid bound,
    and bisection makes it tight. LB = max_i LB_i.
    """
    c, r = problem.carrier, problem.rover
    xy, z, reach = _reach(problem)
    start = np.array(problem.start[:2], dtype=float)
    best = 0.0
    for (x, y), zi, rho in zip(xy.tolist(), z.tolist(), reach.tolist(), strict=True):
        L = math.hypot(x - start[0], y - start[1])

        def car(d: float) -> float:
            return leg_time(d, c.motion)

        def rov(d: float, L: float = L, zi: float = zi) -> float:
            return leg_time(math.hypot(L - d, zi), r)

        lo, hi = max(0.0, L - rho), L
        if car(lo) >= rov(lo):
            bound = car(lo)
        elif car(hi) <= rov(hi):
            bound = rov(hi)
        else:
            for _ in range(_BISECT):
                mid = 0.5 * (lo + hi)
                if car(mid) < rov(mid):
                    lo = mid
                else:
                    hi = mid
            bound = max(car(lo), rov(hi))
        best = max(best, bound + c.collect_stop_time)
    return best


def _stops_bound(problem: CollectProblem) -> float:
    """Argument. Two rovers can share a stop only if their reach discs meet: |g_a − g_b| ≤ ρ_a + ρ_b.
    A set of rovers pairwise farther apart than that (chosen greedily, nearest the start first)
    needs one stop each: K stops, K loads. The stops m_a serving them satisfy
    |m_a − m_b| ≥ |g_a − g_b| − ρ_a − ρ_b and |start − m_a| ≥ |start − g_a| − ρ_a, and the carrier's
    path from the start through them contains a spanning tree of them, so it is at least the
    minimum spanning tree W under those reduced distances; driving it takes ≥ leg_c(W) (see
    ``_rover_bound``). The last of the K loads ends no earlier than leg_c(W) + K · load_time, and
    the makespan (the last departure) is at least that.
    """
    xy, _, reach = _reach(problem)
    carrier = problem.carrier
    return separated_stops_bound(xy, reach, problem.start[:2], carrier.motion, carrier.collect_stop_time)


