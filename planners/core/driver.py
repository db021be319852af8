"""The one search driver of the open-space planners (deployment, ch. 4; collection, ch. 5).

PyVRP's shape: the problem supplies its evaluator and its moves (a ``SearchSpace``: whether a cluster
fits one stop, the quick placement of a cluster list, the final placement, the smoothed placement,
the makespan of the plan a route becomes, the cheap moves of its quick descent); the driver supplies
the sequence and the budget, the same for both:

1. the quick descent (``planners.core.moves.quick_descent``) on the problem's constructed route;
2. both placed finely, the moved route and (small problems) the unimproved one: the faster kept;
3. tiny problems: every ordered partition (``planners.core.partitions``), and with a budget the
   partitions ranked on a finer placement when the problem has one (``SearchSpace.ranking``);
4. the fine descent (every move scored on the final placement): small problems, or a budget;
5. a budget: the smoothed descent (short routes), then the iterated local search until it is spent
   or the search has converged (``ILS_PATIENCE`` kicks per item without a new best);
6. short routes: the fastest of the candidates as the plan will fly (``SearchSpace.flown``).

The tuning constants live here, once.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Sequence
from typing import Protocol, TypeVar

from planners.core.moves import (
    SMOOTH_MOVES,
    Move,
    deadline,
    fine_descent,
    iterated_search,
    quick_descent,
    remembered,
)
from planners.core.partitions import best_partition, ranked_partitions
from planners.core.trace import Trace, untraced

FINE_UPTO = 12  # items: up to this many, the final placement is fine (1 mm), the unimproved route's too
FINE_MOVES_UPTO = 8  # items: up to this many, every move is also scored on the final placement
EXHAUSTIVE_UPTO = 5  # up to this many, every ordered partition is scored on the quick placement ...
EXHAUSTIVE_KEEP = 6  # ... and this many of the fastest placed finely
SCREEN_KEEP = 3  # a budget: the partitions fastest on the ranking placement, then on the smoothed one
EVERY_FINE_UPTO = 5  # up to this many, the fine descent places every change finely (no slack)
FINE_SLACK = 0.15  # otherwise: changes whose quick route is this much slower are not placed finely
SMOOTH_UPTO = 8  # items: up to this many, the final stops are re-placed on the smoothed makespan
COARSE_TOL = 5e-2  # m: the final placement's last step on larger problems (1 mm on small ones)
ILS_PATIENCE = 20  # kicks per item without a new best before the anytime search gives up


class Routed(Protocol):
    """What the driver reads of a route: its clusters in visiting order and its makespan."""

    clusters: list[list[int]]
    makespan: float


R = TypeVar("R", bound=Routed)


class SearchSpace(Protocol[R]):
    """The problem side of the search: its evaluator (placements and makespans) and its moves."""

    size: int  # tasks (rovers)
    cheap: Sequence[Move]  # the quick descent's moves on long routes

    def fits(self, cluster: Sequence[int]) -> bool:
        """Whether one stop can serve ``cluster``."""

    def rebuild(self, clusters: list[list[int]]) -> R:
        """The quick placement of ``clusters``."""

    def finish(self, route: R, small: bool, improve: bool) -> R:
        """The final placement of ``route``'s stops (fine when ``small``; without ``improve``: the
        placement of the unimproved plan)."""

    def smooth(self, route: R) -> R:
        """``route``'s stops re-placed on the smoothed makespan (``planners.core.smooth``)."""

    def flown(self, route: R) -> float:
        """The makespan of the plan ``route`` becomes (coordinates snapped as the plan builder does)."""

    def ranking(self) -> Callable[[list[list[int]]], R] | None:
        """A placement finer than ``rebuild`` to rank tiny problems' partitions on with a budget, or None."""


def search(space: SearchSpace[R], route: R, *, improve: bool = True, budget_ms: float | None = None,
           t0: float | None = None, seed: int = 0, tiny_search: bool = True, trace: Trace = untraced) -> R:
    """The search sequence (module docstring) from ``route``, the problem's constructed route.
    ``tiny_search`` False leaves out the searches of tiny problems (every ordered partition, fine
    moves, smoothed stops): a quick plan for screening many. ``budget_ms`` (from ``t0``,
    perf_counter) bounds the anytime part; ``seed`` its kicks. ``trace`` is called with each
    phase's name and the makespan after it."""
    n = space.size
    small = n <= FINE_UPTO
    gated = n if tiny_search else math.inf  # the size the tiny problems' searches go by (without: none)
    finish = remembered(lambda r: space.finish(r, small, improve))
    if not improve:
        best = finish(route)
        trace("final placement", best.makespan)
        return best

    @remembered
    def smoothed(r: R) -> R:  # short routes: also on the smoothed makespan
        return space.smooth(finish(r)) if gated <= SMOOTH_UPTO else finish(r)

    stop = deadline(budget_ms, t0)
    rank = space.ranking()
    early = None  # a budget: tiny problems first screen every partition on finer stops (while it lasts)
    if stop is not None and gated <= EXHAUSTIVE_UPTO and rank is not None:
        early = screened(n, space.fits, rank, route, smoothed, stop)
    # group and order moves (planners.core.moves), scored on the quick placement ...
    moved = quick_descent(route, space.fits, cheap=space.cheap)
    trace(_phase(space.cheap), moved.makespan)
    best = finish(moved)
    if small and moved is not route:  # (large routes: the moves' route alone is placed finely)
        today = finish(route)
        best = today if today.makespan < best.makespan else best
    trace("final placement", best.makespan)
    if gated <= EXHAUSTIVE_UPTO:  # tiny: every ordered partition too
        every = best_partition(n, space.fits, space.rebuild, finish, EXHAUSTIVE_KEEP)
        best = every if every is not None and every.makespan < best.makespan else best
        best = early if early is not None and early.makespan < best.makespan else best
    if gated <= FINE_MOVES_UPTO or stop is not None:  # ... and on the final placement
        best = fine_descent(best, space.fits, space.rebuild, finish,
                            stop if gated > FINE_MOVES_UPTO else None,
                            slack=FINE_SLACK if stop is None and gated > EVERY_FINE_UPTO else math.inf)
    quick = best
    if stop is not None and gated <= SMOOTH_UPTO:  # a budget: the moves scored on the smoothed stops first
        best = fine_descent(best, space.fits, space.rebuild, smoothed, stop, slack=math.inf,
                            moves=SMOOTH_MOVES)
    if stop is not None:  # anytime: iterated local search until the budget or convergence
        best = iterated_search(best, space.fits, space.rebuild, smoothed, random.Random(seed), stop,
                               max_fails=ILS_PATIENCE * n)
    if gated <= SMOOTH_UPTO:  # timed as the plan will fly (its builder snaps a stop millimetres on)
        last = space.smooth(best)
        cands = (last, space.smooth(quick), quick) if stop is not None else (last, quick)
        best = min(cands, key=space.flown)
    trace("tiny-problem and budget searches", best.makespan)
    return best


def screened(n: int, fits: Callable[[Sequence[int]], bool], rank: Callable[[list[list[int]]], R], best: R,
             smoothed: Callable[[R], R], stop: Callable[[], bool]) -> R:
    """Tiny problems with a budget: every ordered partition ranked on the ``rank`` placement (the
    quick placement can tie dozens of partitions on one slow rover), the ``SCREEN_KEEP`` fastest
    placed finely and on the smoothed makespan while the budget lasts; ``best`` when none is faster."""
    if stop():
        return best
    for r in ranked_partitions(n, fits, rank, SCREEN_KEEP):
        if stop():
            break
        cand = smoothed(r)
        best = cand if cand.makespan < best.makespan else best
    return best


def _phase(moves: Sequence[Move]) -> str:
    """The quick descent's phase name from its moves, e.g. "swap, relocate and merge"."""
    names = [getattr(m, "__name__", "move").removesuffix("_nearest") for m in moves]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
