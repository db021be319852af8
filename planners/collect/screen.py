"""Lower bounds of many local changes of a collection route at once (numpy): a screen for the
cluster search (``planners.core.search.split_loop``), which then scores exactly
(``Route.replace``) only the changes that might make the route faster.

A change (i, pieces, count) places stops lo..hi−1 afresh (``Route.replace``) and drives on to the
first kept stop m, whose place, rovers and everything after it stay. Whatever the new stops' places:

* the carrier leaves stop lo − 1 (or the start) at the same time t0 from the same point P0;
* it drives from P0 through the new stops to stop m; every stop lies in its cluster's reach discs,
  which bounds the path's length and its first and last hops' lengths from below, and every hop
  costs at least the travel time of its length (turns cost more); travel time is concave, so the
  least the hops can cost is found at a corner of those bounds (``_drive``; the travel time is
  ``planners.core.timing.travel_times``, the time model's numpy form);
* it loads at each of the hi − lo new stops and at stop m, and leaves m no earlier than its
  rovers' landing + load;
* from m on, the route ends as before (``Route.end_from``) except for the turn at m (the heading
  into m changed): the hop into m + 1 is counted without its turn.

The bound is close for changes that add a stop (Algorithm 5.2's divisions: the extra load is rarely
won back on a route the carrier's driving dominates). ``screen`` returns it less ``MARGIN``
(rounding); changes with no kept stop after them get −inf.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from planners.core.timing import travel_times

if TYPE_CHECKING:
    from planners.collect.path import PathBuilder, Route

Change = tuple[int, list[list[int]], int]
MARGIN = 1e-6  # s: far above the bound's rounding, far below any gain the search keeps


def screen(route: Route, changes: Sequence[Change]) -> np.ndarray:
    """A lower bound of ``route.replace(*change)[0]`` for every change, −inf where unknown."""
    return bound(route, changes) - MARGIN


def bound(route: Route, changes: Sequence[Change]) -> np.ndarray:
    """The module docstring's bound of every change's makespan, −inf where it has none."""
    b, n = route.b, len(route.clusters)
    out = np.full(len(changes), -np.inf)
    ok = [c for c, (i, _, count) in enumerate(changes) if i + count < n]
    if not ok:
        return out
    i = np.array([changes[c][0] for c in ok], dtype=np.intp)
    lo = np.maximum(i - 1, 0) if b.replace_before else i
    m = i + np.array([changes[c][2] for c in ok], dtype=np.intp)  # the first kept stop (old index)
    placed = [[*route.clusters[a:j], *changes[c][1]]  # the clusters whose stops are placed afresh
              for c, a, j in zip(ok, lo.tolist(), i.tolist(), strict=True)]
    pos = np.array(route.positions, dtype=float)
    prev = np.where((lo == 0)[:, None], np.array(b.start, dtype=float), pos[np.maximum(lo - 1, 0)])
    t0 = np.where(lo == 0, 0.0, np.array(route.eta)[np.maximum(lo - 1, 0)])
    drive = _drive(b, prev, pos[m], placed)
    leave = np.maximum(t0 + drive + np.array([len(p) for p in placed]) * b.load, np.array(route.ready)[m])
    leave = leave + b.load  # from stop m
    nxt = np.minimum(m + 1, n - 1)
    turnless = travel_times(_length(pos[nxt] - pos[m]), b.carrier.motion)
    rest = np.where(m + 1 >= n, 0.0, np.array(route.after)[m] - np.array(route.hop)[nxt] + turnless)
    out[ok] = np.maximum(leave + rest, np.array(route.late)[m])
    return out


def _drive(b: PathBuilder, p: np.ndarray, q: np.ndarray,
           placed: Sequence[Sequence[Sequence[int]]]) -> np.ndarray:
    """Per change, a lower bound of the carrier's travel time from ``p`` through stops serving the
    clusters ``placed`` (in order) to ``q``. Every stop lies in its cluster's discs (ground g,
    radius ρ), so the path is at least E = max(|p − q|, |p − g| + |g − q| − 2ρ over every placed
    rover) long, its first hop at least l1 = max(|p − g| − ρ) over the first cluster and its last
    l2 over the last. Travel time f is concave and increasing with f(0) = 0: over hop lengths
    x_j ≥ l_j summing to E, the least Σ f(x_j) puts every hop but one at its least."""
    first = _farthest_out(b, p, [c[0] for c in placed])
    last = _farthest_out(b, q, [c[-1] for c in placed])
    rovers = [[r for c in cs for r in c] for cs in placed]
    lens = np.fromiter(map(len, rovers), dtype=np.intp, count=len(rovers))
    flat = np.fromiter(itertools.chain.from_iterable(rovers), dtype=np.intp, count=int(lens.sum()))
    g, rad = b.inst.ground[flat], b.inst.radii[flat]
    via = (_length(np.repeat(p, lens, axis=0) - g) + _length(g - np.repeat(q, lens, axis=0)) - 2.0 * rad)
    e = np.maximum(_length(q - p), np.maximum.reduceat(via, np.cumsum(lens) - lens))
    f = functools.partial(travel_times, motion=b.carrier.motion)
    ends = f(first) + f(last)
    middle = np.where(np.array([len(c) for c in placed]) >= 2,
                      ends + f(np.maximum(e - first - last, 0.0)), np.inf)
    return np.minimum(middle, np.minimum(f(last) + f(np.maximum(e - last, first)),
                                         f(first) + f(np.maximum(e - first, last))))


def _farthest_out(b: PathBuilder, p: np.ndarray, clusters: Sequence[Sequence[int]]) -> np.ndarray:
    """Per row, the largest max(|p − g| − ρ, 0) over cluster's rovers: how far ``p`` lies at least
    from the cluster's common reach region."""
    lens = np.fromiter(map(len, clusters), dtype=np.intp, count=len(clusters))
    flat = np.fromiter(itertools.chain.from_iterable(clusters), dtype=np.intp, count=int(lens.sum()))
    out = _length(np.repeat(p, lens, axis=0) - b.inst.ground[flat]) - b.inst.radii[flat]
    return np.maximum(np.maximum.reduceat(out, np.cumsum(lens) - lens), 0.0)


def _length(d: np.ndarray) -> np.ndarray:
    """The length of every row's 2D vector."""
    return np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
