"""Improve an allocation by moving groups and single items between teams, scored exactly.

The objective is the teams' makespans sorted from the latest down, compared lexicographically:
first the mission's makespan (the latest team's), then the next latest, and so on, so that two
teams tied at the top can be relieved one after the other. Every candidate is scored by the team
planners (``TeamScorer``); a move is kept only when it improves the objective, so the result is
never worse than where the search started.

Moves, all taken from the latest team ``a`` to another team ``b``: a whole group (what one stop
can serve), a single item, and — when ``b``'s deck is full — a swap of an item of ``a`` with the
item of ``b`` nearest ``a``'s start. Candidates nearest ``b`` (its start or its items) go first;
the first improving one is applied. The search ends when no move improves, or after
``max_calls`` planner calls.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from planners.teams.score import TeamScorer

_EPS = 1e-9


@dataclass(frozen=True)
class _Move:
    a: int
    b: int
    give: frozenset[int]  # from a to b
    take: frozenset[int] = frozenset()  # from b to a (a swap)


class Allocation:
    """Team index per item, each team's share and makespan."""

    def __init__(self, scorer: TeamScorer, team_of: list[int]) -> None:
        self.scorer = scorer
        self.team_of = list(team_of)
        n = scorer.problem.n_teams
        self.shares = [frozenset(i for i, k in enumerate(team_of) if k == t) for t in range(n)]
        self.spans = [scorer.makespan(t, self.shares[t]) for t in range(n)]

    def key(self) -> tuple[float, ...]:
        return tuple(sorted(self.spans, reverse=True))

    def makespan(self) -> float:
        return max(self.spans)

    def apply(self, m: _Move, span_a: float, span_b: float) -> None:
        self.shares[m.a] = (self.shares[m.a] - m.give) | m.take
        self.shares[m.b] = (self.shares[m.b] - m.take) | m.give
        self.spans[m.a], self.spans[m.b] = span_a, span_b
        for i in m.give:
            self.team_of[i] = m.b
        for i in m.take:
            self.team_of[i] = m.a


def better(new: tuple[float, ...], old: tuple[float, ...]) -> bool:
    """Lexicographically smaller by more than rounding."""
    for x, y in zip(new, old, strict=True):
        if x < y - _EPS:
            return True
        if x > y + _EPS:
            return False
    return False


def improve(alloc: Allocation, groups: list[list[int]], max_calls: int) -> Allocation:
    """Apply improving moves (module docstring) until none is left or the budget is spent."""
    scorer = alloc.scorer
    xy = np.array([q[:2] for q in scorer.problem.positions()], dtype=float).reshape(-1, 2)
    starts = np.array([s[:2] for s in scorer.problem.starts()], dtype=float).reshape(-1, 2)
    while scorer.calls < max_calls:
        a = int(np.argmax(alloc.spans))
        for move in _candidates(alloc, a, groups, xy, starts):
            if scorer.calls >= max_calls:
                break
            if _try(alloc, move):
                break
        else:
            break
    return alloc


def _try(alloc: Allocation, m: _Move) -> bool:
    scorer = alloc.scorer
    span_b = scorer.makespan(m.b, (alloc.shares[m.b] - m.take) | m.give)
    if span_b >= alloc.spans[m.a] - _EPS:  # b would become as late as a is now: no gain
        return False
    span_a = scorer.makespan(m.a, (alloc.shares[m.a] - m.give) | m.take)
    spans = list(alloc.spans)
    spans[m.a], spans[m.b] = span_a, span_b
    if better(tuple(sorted(spans, reverse=True)), alloc.key()):
        alloc.apply(m, span_a, span_b)
        return True
    return False


def _candidates(alloc: Allocation, a: int, groups: list[list[int]], xy: np.ndarray,
                starts: np.ndarray) -> Iterator[_Move]:
    mine = alloc.shares[a]
    parts = [frozenset(g) & mine for g in groups]
    pieces = list(dict.fromkeys([p for p in parts if p] + [frozenset([i]) for i in sorted(mine)]))
    problem = alloc.scorer.problem
    moves: list[tuple[float, _Move]] = []
    for b in range(problem.n_teams):
        if b == a:
            continue
        anchors = np.vstack([starts[b:b + 1], xy[sorted(alloc.shares[b])].reshape(-1, 2)])
        room = problem.capacity(b) - len(alloc.shares[b])
        for piece in pieces:
            centre = xy[sorted(piece)].mean(axis=0)
            near = float(np.min(np.linalg.norm(anchors - centre, axis=1)))
            if len(piece) <= room:
                moves.append((near, _Move(a, b, piece)))
            elif len(piece) == 1 and alloc.shares[b]:
                theirs = sorted(alloc.shares[b])
                j = theirs[int(np.argmin(np.linalg.norm(xy[theirs] - starts[a], axis=1)))]
                moves.append((near, _Move(a, b, piece, frozenset([j]))))
    moves.sort(key=lambda t: t[0])
    for _, m in moves:
        yield m
