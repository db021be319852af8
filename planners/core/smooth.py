"""Placing a short route's stops on a smoothed makespan (beyond the dissertation).

The makespan of a route is a max-plus expression of its stops' positions (deployment: the latest
of the stops' last arrivals; collection, eq. 5.2: η_k = max(η_{k−1} + hop, ready_k) + load). Where
two terms tie, e.g. the carrier arrives at a stop just as its last rover lands, moving one stop
alone cannot help: the carrier must get there earlier *and* the rovers land sooner, which needs two
stops to move at once. A compass search on the exact makespan stops at such a kink. On the smoothed
makespan, every max replaced by τ·log Σ exp(·/τ), moving either stop helps a little, so the same
compass search slides along the kink; τ shrinks to 0 in a few stages and the exact makespan of
every stage's end decides (``planners.core.timing`` times every hop either way).

Quadratic in the route's length (every trial re-times the whole route): for short routes only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from planners.core.geometry import COMPASS

Point2 = tuple[float, float]
# stages of τ, relative to the makespan; the last (0) is the exact makespan
TAUS = (0.03, 0.008, 0.002, 0.0)
COARSE = 8  # the smoothed stages' last step, in multiples of the exact stage's


def smooth_max(a: float, b: float, tau: float) -> float:
    """max(a, b) smoothed by τ (τ·log(e^{a/τ} + e^{b/τ}); the plain max for τ = 0)."""
    if tau <= 0.0:
        return a if a > b else b
    m = a if a > b else b
    return m + tau * math.log(math.exp((a - m) / tau) + math.exp((b - m) / tau))


def smooth_compass(cost: Callable[[Sequence[Point2], float], float],
                   exact: Callable[[Sequence[Point2]], float], starts: Sequence[Sequence[Point2]],
                   step: float, tol: float = 1e-3, taus: Sequence[float] = TAUS) -> list[Point2]:
    """Minimise ``cost(positions, τ)`` (inf where a stop cannot serve its cluster) from each of
    ``starts`` by a compass search over one stop at a time (8 directions, first improvement,
    halving the step to ``tol``) for each τ of ``taus`` (relative to the exact makespan of the
    first start); returns the positions of the stage whose ``exact`` makespan is lowest (the first
    start when none is lower)."""
    best_pos = list(starts[0])
    best = scale = exact(best_pos)
    for start in starts:
        pos = list(start)
        for stage, rel in enumerate(taus):
            tau = rel * scale
            cur = cost(pos, tau)
            if cur == math.inf:
                break
            s = step if stage == 0 else step / 4
            last = tol if stage + 1 == len(taus) else tol * COARSE  # the smoothed stages stop coarser
            while s > last:
                improved = False
                for k in range(len(pos)):
                    x, y = pos[k]
                    for dx, dy in COMPASS:
                        pos[k] = (x + s * dx, y + s * dy)
                        c = cost(pos, tau)
                        if c < cur - 1e-12:
                            cur, improved = c, True
                            break
                        pos[k] = (x, y)
                if not improved:
                    s /= 2
            t = exact(pos)
            if t < best - 1e-9:
                best, best_pos = t, list(pos)
    return best_pos
