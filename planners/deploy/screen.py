"""Many local changes of a deployment route scored at once with numpy: a screen for the cluster
search (``planners.core.search``), which then scores exactly (``Route.replace``) only the changes
that might make the route faster.

A change (i, pieces, count) re-places the stops around it as ``Route.replace`` does: the stop
before it, the pieces and the stop after them by eq. 4.21–4.23 (``max_range_point``), then the
first kept stop and the turn after it; every later stop shifts in time. The screen runs the same
steps for every change at once, composed only of the numpy twins of the scalar functions that
``Route.replace`` calls: ``carrier_steps`` and ``leg_times`` beside ``carrier_step`` and
``leg_time`` in the time model (``planners.core.timing``), ``max_range_points`` beside
``max_range_point`` (``planners.deploy.cluster``). Its numbers (``estimate``) differ from the exact
ones by rounding only (a property test checks 1e-9 on random routes), so ``screen`` returns them
less ``MARGIN`` as lower bounds. Changes it does not score (at the route's start, next to its last
two stops, which are placed together, or with a hop of almost no length, where a heading is lost)
get −inf.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from planners.core.timing import carrier_steps, leg_times
from planners.deploy.cluster import max_range_points

if TYPE_CHECKING:
    from planners.deploy.cluster import ClusterGeometry
    from planners.deploy.path import Route

Change = tuple[int, list[list[int]], int]
MARGIN = 1e-6  # s: far above the screen's rounding, far below any gain the search keeps
SHORT2 = 1e-6  # m²: a hop this short is scored exactly (its heading is rounding)


def screen(route: Route, changes: Sequence[Change]) -> np.ndarray:
    """A lower bound of ``route.replace(*change)[0]`` for every change, −inf where unknown."""
    return estimate(route, changes) - MARGIN


def estimate(route: Route, changes: Sequence[Change]) -> np.ndarray:
    """``route.replace(*change)[0]`` of every change, up to rounding (the same steps on the numpy
    forms of the time model), −inf where unknown."""
    out = np.full(len(changes), -np.inf)
    groups: dict[tuple[int, int], list[int]] = defaultdict(list)
    n_old = len(route.clusters)
    for c, (i, pieces, count) in enumerate(changes):
        n_new = n_old - count + len(pieces)
        if i >= 1 and i + len(pieces) + 1 < n_new - 2:  # replace() places a window of stops lo..hi-1
            groups[(len(pieces), count)].append(c)
    for (p, count), idx in groups.items():
        out[idx] = _window(route, [changes[c] for c in idx], p, count)
    return out


def _window(route: Route, changes: Sequence[Change], p: int, count: int) -> np.ndarray:
    """``replace`` for changes of ``p`` pieces for ``count`` clusters at i >= 1 (lo = i − 1,
    hi = i + p + 1, the first kept stop m = i + count + 1, all before the last two stops)."""
    b = route.b
    inst, c, unload = b.inst, b.carrier, b.unload
    w = p + 2  # stops placed: i − 1, the pieces, old i + count
    i = np.array([ch[0] for ch in changes])
    # per change, the w stops' clusters and the next one: centre x, y and slack (the route's own
    # clusters from its arrays, the pieces' looked up)
    mine = _geo_rows(route.geos)
    pieces = _geo_rows([inst.geometry(q) for _, qs, _ in changes for q in qs]).reshape(len(changes), p, 3)
    geo = np.concatenate([mine[i - 1, None], pieces, mine[i + count, None], mine[i + count + 1, None]],
                         axis=1)
    cx, cy, slack = geo[..., 0], geo[..., 1], np.maximum(geo[..., 2], 0.0)
    members = [m for at, qs, _ in changes for m in (route.clusters[at - 1], *qs, route.clusters[at + count])]
    lo = i - 1
    first = lo == 0
    prev_i = np.maximum(lo - 1, 0)
    pos = np.array(route.positions)
    arrive, heading = np.array(route.arrive), np.array(route.heading)
    px = np.where(first, b.start[0], pos[prev_i, 0])
    py = np.where(first, b.start[1], pos[prev_i, 1])
    t = np.where(first, 0.0, arrive[prev_i] + unload)
    h = np.where(first, inst.problem.heading, heading[prev_i])
    worst = np.where(first, 0.0, np.array(route.head)[prev_i])
    short = np.zeros(len(changes), dtype=bool)
    qxs, qys, ts = [], [], []
    for k in range(w):
        qx, qy = max_range_points(px, py, cx[:, k], cy[:, k], slack[:, k], cx[:, k + 1], cy[:, k + 1])
        dx, dy = qx - px, qy - py
        short |= dx * dx + dy * dy < SHORT2
        dt, h = carrier_steps(dx, dy, h, c)
        t = t + (dt + unload)
        qxs.append(qx)
        qys.append(qy)
        ts.append(t)
        px, py = qx, qy
    # every placed stop's farthest task at once: the members in one flat array, (change, stop) order
    far = _farthest(inst.xyz, members, np.stack(qxs, axis=1).ravel(), np.stack(qys, axis=1).ravel())
    done = np.stack(ts, axis=1) + leg_times(np.sqrt(far), b.rover).reshape(len(changes), w)
    worst = np.maximum(worst, done.max(axis=1))
    m = i + count + 1  # the first kept stop (old index)
    dx, dy = pos[m, 0] - px, pos[m, 1] - py
    short |= dx * dx + dy * dy < SHORT2
    dt, h = carrier_steps(dx, dy, h, c)
    t = t + (dt + unload)
    worst = np.maximum(worst, t + np.array(route.fly)[m])
    dt, _ = carrier_steps(pos[m + 1, 0] - pos[m, 0], pos[m + 1, 1] - pos[m, 1], h, c)
    worst = np.maximum(worst, np.array(route.tail)[m + 1] + (t + dt - arrive[m + 1]))
    return np.where(short, -np.inf, worst)


def _geo_rows(geos: Sequence[ClusterGeometry]) -> np.ndarray:
    """(centre x, centre y, slack) of each cluster, one row each."""
    return np.array([(g.center[0], g.center[1], g.slack) for g in geos], dtype=float).reshape(-1, 3)


def _farthest(xyz: np.ndarray, members: Sequence[Sequence[int]], qx: np.ndarray,
              qy: np.ndarray) -> np.ndarray:
    """Per cluster j, the largest squared distance from the ground point (qx[j], qy[j]) to its tasks."""
    lens = np.fromiter(map(len, members), dtype=np.intp, count=len(members))
    flat = np.fromiter(itertools.chain.from_iterable(members), dtype=np.intp, count=int(lens.sum()))
    task = xyz[flat]
    ex, ey = task[:, 0] - np.repeat(qx, lens), task[:, 1] - np.repeat(qy, lens)
    return np.maximum.reduceat(ex * ex + ey * ey + task[:, 2] ** 2, np.cumsum(lens) - lens)
