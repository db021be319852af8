"""Many local changes of a deployment route scored at once with numpy: a screen for the cluster
search (``planners.core.search``), which then scores exactly (``Route.replace``) only the changes
that might make the route faster.

A change (i, pieces, count) re-places the stops around it as ``Route.replace`` does: the stop
before it, the pieces and the stop after them by eq. 4.21–4.23 (``max_range_point``), then the
first kept stop and the turn after it; every later stop shifts in time. The screen runs the same
steps on the numpy forms of the time model (``planners.core.timing``) for every change at once;
its numbers differ from the exact ones by rounding only, so it returns them less ``MARGIN`` as
lower bounds. Changes it does not score (at the route's start, next to its last two stops, which
are placed together, or with a hop of almost no length, where a heading is lost) get −inf.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from planners.core.timing import carrier_steps, leg_times

if TYPE_CHECKING:
    from planners.deploy.cluster import ClusterGeometry
    from planners.deploy.path import Route

Change = tuple[int, list[list[int]], int]
MARGIN = 1e-6  # s: far above the screen's rounding, far below any gain the search keeps
SHORT2 = 1e-6  # m²: a hop this short is scored exactly (its heading is rounding)


def screen(route: Route, changes: Sequence[Change]) -> np.ndarray:
    """A lower bound of ``route.replace(*change)[0]`` for every change, −inf where unknown."""
    out = np.full(len(changes), -np.inf)
    groups: dict[tuple[int, int], list[int]] = defaultdict(list)
    n_old = len(route.clusters)
    for c, (i, pieces, count) in enumerate(changes):
        n_new = n_old - count + len(pieces)
        if i >= 1 and i + len(pieces) + 1 < n_new - 2:  # replace() places a window of stops lo..hi-1
            groups[(len(pieces), count)].append(c)
    for (p, count), idx in groups.items():
        out[idx] = _window(route, [changes[c] for c in idx], p, count) - MARGIN
    return out


def _window(route: Route, changes: Sequence[Change], p: int, count: int) -> np.ndarray:
    """``replace`` for changes of ``p`` pieces for ``count`` clusters at i >= 1 (lo = i − 1,
    hi = i + p + 1, the first kept stop m = i + count + 1, all before the last two stops)."""
    b = route.b
    inst, c, unload = b.inst, b.carrier, b.unload
    w = p + 2  # stops placed: i − 1, the pieces, old i + count
    geos: list[ClusterGeometry] = []  # per change: the w stops' clusters and the next one
    members: list[Sequence[int]] = []
    for at, pieces, _ in changes:
        geos += [route.geos[at - 1], *(inst.geometry(q) for q in pieces), route.geos[at + count],
                 route.geos[at + count + 1]]
        members += [route.clusters[at - 1], *pieces, route.clusters[at + count]]
    cx = np.array([g.center[0] for g in geos]).reshape(len(changes), w + 1)
    cy = np.array([g.center[1] for g in geos]).reshape(len(changes), w + 1)
    slack = np.maximum(np.array([g.slack for g in geos]), 0.0).reshape(len(changes), w + 1)
    width = max(len(m) for m in members)
    rows = [j for m in members for j in (*m, *(m[0],) * (width - len(m)))]  # padded: a task repeated
    task = inst.xyz[np.array(rows)].reshape(len(changes), w, width, 3)
    tx, ty, z2 = task[..., 0], task[..., 1], task[..., 2] ** 2  # (changes, w, width)
    i = np.array([ch[0] for ch in changes])
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
    for k in range(w):
        qx, qy = _max_range_point(px, py, cx[:, k], cy[:, k], slack[:, k], cx[:, k + 1], cy[:, k + 1])
        dx, dy = qx - px, qy - py
        short |= dx * dx + dy * dy < SHORT2
        dt, h = carrier_steps(dx, dy, h, c)
        t = t + (dt + unload)
        ex, ey = tx[:, k] - qx[:, None], ty[:, k] - qy[:, None]
        far = (ex * ex + ey * ey + z2[:, k]).max(axis=1)
        worst = np.maximum(worst, t + leg_times(np.sqrt(far), b.rover))
        px, py = qx, qy
    m = i + count + 1  # the first kept stop (old index)
    dx, dy = pos[m, 0] - px, pos[m, 1] - py
    short |= dx * dx + dy * dy < SHORT2
    dt, h = carrier_steps(dx, dy, h, c)
    t = t + (dt + unload)
    worst = np.maximum(worst, t + np.array(route.fly)[m])
    dt, _ = carrier_steps(pos[m + 1, 0] - pos[m, 0], pos[m + 1, 1] - pos[m, 1], h, c)
    worst = np.maximum(worst, np.array(route.tail)[m + 1] + (t + dt - arrive[m + 1]))
    return np.where(short, -np.inf, worst)


def _max_range_point(px: np.ndarray, py: np.ndarray, cx: np.ndarray, cy: np.ndarray, slack: np.ndarray,
                     nx: np.ndarray, ny: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``planners.deploy.cluster.max_range_point`` of every row (numpy)."""
    dx, dy = nx - px, ny - py
    n2 = dx * dx + dy * dy
    s = np.where(n2 < 1e-18, 0.0, ((cx - px) * dx + (cy - py) * dy) / np.where(n2 < 1e-18, 1.0, n2))
    fx, fy = px + s * dx, py + s * dy
    ox, oy = fx - cx, fy - cy
    off = np.hypot(ox, oy)
    inside = off <= slack
    scale = slack / np.where(inside, 1.0, off)
    return np.where(inside, fx, cx + ox * scale), np.where(inside, fy, cy + oy * scale)
