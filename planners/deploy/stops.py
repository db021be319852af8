"""One deployment stop moved, the others kept (the polish of ``planners.deploy.lee``): its cost on
the exact time model, and for long routes many stops searched at once with numpy.

Moving stop k changes only the hops into k and k + 1 and the turn at k + 1 (``stop_cost``);
stops three apart change disjoint hops, so a class of them (every third stop) can be searched
together, each with the others' stops fixed: one numpy call scores 16 compass points (8
directions, at a step and at half of it) of every stop of the class. The time model is
``planners.core.timing`` (its numpy forms); the caller re-times the moved route exactly and keeps
it only when it is faster.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from planners.core.geometry import COMPASS, compass_search
from planners.core.native import kernels
from planners.core.problem import Point2
from planners.core.timing import Step, carrier_hop, carrier_stepper, carrier_steps, leg_times, travel_times
from planners.deploy.cluster import max_range_point
from planners.deploy.path import PathBuilder, Route

HANDOFF = 6  # stops: when no more of the class are still moving, each finishes on its own
_TAU = 2.0 * np.pi
_TAU_F = float(_TAU)  # the same number as a Python float (the same remainders, without numpy's scalars)
_DX = np.array([d[0] for d in COMPASS])
_DY = np.array([d[1] for d in COMPASS])
_DX2, _DY2 = np.tile(_DX, 2), np.tile(_DY, 2)  # the points at a step and at half of it


def stop_cost(builder: PathBuilder, r: Route, k: int) -> Callable[[float, float], float]:
    """Makespan of route ``r`` with stop k moved to (x, y), the others kept, or inf where a task of
    stop k is out of reach: only the legs into k and k + 1 and the turn at k + 1 change; later
    stops shift in time by the same amount. The polish calls it
    thousands of times: the hops are ``planners.core.timing.carrier_stepper``'s."""
    b, pos, unload, d2max = builder, r.positions, builder.unload, builder.inst.d ** 2
    c = b.carrier
    w = c.turn_rate
    step, leg = carrier_stepper(c), b.leg
    rows = [b.inst.pts[i] for i in r.clusters[k]]
    rows2 = [(x, y, z * z) for x, y, z in rows]
    if k == 0:
        (px, py), t0, h0 = b.start, 0.0, b.inst.problem.heading
    else:
        (px, py), t0, h0 = pos[k - 1], r.arrive[k - 1] + unload, r.heading[k - 1]
    head = r.head[k - 1] if k else 0.0  # stops before k are not affected
    n = len(pos)
    nx1 = ny1 = 0.0
    done1 = arrive1 = 0.0
    if k + 1 < n:
        (nx1, ny1), done1, arrive1 = pos[k + 1], r.done[k + 1], r.arrive[k + 1]
    # the hop k + 1 → k + 2 keeps its length; only the turn at k + 1 depends on stop k
    h12: float | None = None
    hop12 = tail2 = arrive2 = 0.0
    if k + 2 < n:
        qx, qy = pos[k + 2]
        if (qx - nx1) ** 2 + (qy - ny1) ** 2 > 1e-18:
            h12 = math.atan2(qy - ny1, qx - nx1)
            hop12 = carrier_hop(pos[k + 1], pos[k + 2], h12, c)[0]  # travel only (no turn)
        tail2, arrive2 = r.tail[k + 2], r.arrive[k + 2]

    start = (px, py, h0, t0)
    next1 = (nx1, ny1, done1, arrive1) if k + 1 < n else None
    next2 = (hop12, h12, tail2, arrive2) if k + 2 < n else None
    # the compiled twin when it is built: the same floats
    make = deploy_stop_cost if kernels is None else kernels.DeployStopCost
    return make(rows2, d2max, step, leg, start, unload, head, next1, next2, w)


Start = tuple[float, float, float, float]  # where, heading and when the carrier leaves the stop before


def deploy_stop_cost(rows2: Sequence[tuple[float, float, float]], d2max: float, step: Step,
                     leg: Callable[[float], float], start: Start, unload: float, head: float,
                     next1: tuple[float, float, float, float] | None,
                     next2: tuple[float, float | None, float, float] | None,
                     w: float | None) -> Callable[[float, float], float]:
    """``stop_cost``'s cost(x, y) from its fixed data: the tasks' (x, y, z²), the largest squared
    flight, the carrier's step and the rovers' leg, the start (x, y, heading, time), the stops
    before k (``head``: their latest finish), the next stop (x, y, done, arrival) and the one
    after (hop time, heading of the hop or None, tail, arrival), the carrier's turn rate."""
    px, py, h0, t0 = start
    nx1, ny1, done1, arrive1 = next1 if next1 is not None else (0.0, 0.0, 0.0, 0.0)
    hop12, h12, tail2, arrive2 = next2 if next2 is not None else (0.0, None, 0.0, 0.0)
    tau, sqrt, inf = _TAU_F, math.sqrt, math.inf

    def cost(x: float, y: float) -> float:
        far = 0.0
        for tx, ty, z2 in rows2:
            e = (tx - x) ** 2 + (ty - y) ** 2 + z2
            if e > far:
                far = e
        if far > d2max:
            return inf
        dt, h = step(x - px, y - py, h0)
        t = t0 + dt + unload
        worst = head  # (the maxima written out: max(a, b) is a unless b > a)
        v = t + leg(sqrt(far))
        if v > worst:
            worst = v
        if next1 is not None:
            dt, h = step(nx1 - x, ny1 - y, h)
            t1 = t + dt
            v = done1 + (t1 - arrive1)
            if v > worst:
                worst = v
            if next2 is not None:
                dt = hop12
                if h12 is not None and w is not None:
                    turn = (h12 - h) % tau
                    dt += (turn if not tau - turn < turn else tau - turn) / w
                elif h12 is None:
                    dt = 0.0
                v = tail2 + (t1 + unload + dt - arrive2)
                if v > worst:
                    worst = v
        return worst

    return cost


class StopClass:
    """Stops of ``route`` that do not share a hop (k + 2 < len for each): their fixed data as
    arrays (one row per stop) and ``cost(x, y)``, the route's makespan with each row's stop moved
    to the row's points (``stop_cost`` for many stops and points at once)."""

    def __init__(self, builder: PathBuilder, route: Route, ks: Sequence[int]) -> None:
        b, r = builder, route
        self.b, self.ks = b, list(ks)
        unload = b.unload
        width = max(len(r.clusters[k]) for k in ks)
        rows = [j for k in ks for m in (r.clusters[k],) for j in (*m, *(m[0],) * (width - len(m)))]
        task = b.inst.xyz[np.array(rows)].reshape(len(ks), width, 3, 1)  # padded with a repeated task
        self.tx, self.ty, self.z2 = task[:, :, 0], task[:, :, 1], task[:, :, 2] ** 2
        fixed = np.array([(*(b.start if k == 0 else r.positions[k - 1]),
                           b.inst.problem.heading if k == 0 else r.heading[k - 1],
                           0.0 if k == 0 else r.arrive[k - 1] + unload, r.head[k - 1] if k else 0.0,
                           *r.positions[k + 1], r.done[k + 1], r.arrive[k + 1], r.tail[k + 2],
                           r.arrive[k + 2], *r.positions[k + 2]) for k in ks], dtype=float).T[:, :, None]
        (self.px, self.py, self.h0, self.t0, self.head, self.nx, self.ny, self.done1, self.arrive1,
         self.tail2, self.arrive2, qx, qy) = fixed
        qx, qy = qx - self.nx, qy - self.ny
        self.moving12 = qx * qx + qy * qy > 1e-18  # the hop k + 1 → k + 2 has a direction
        self.h12 = np.arctan2(qy, qx)
        self.hop12 = np.where(self.moving12, travel_times(np.sqrt(qx * qx + qy * qy), b.carrier.motion), 0.0)
        self.all_moving12 = bool(self.moving12.all())
        self.d2max = b.inst.d ** 2

    def cost(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Makespan with stop ``ks[i]`` at (x[i, j], y[i, j]), every row at once; inf where out of
        reach."""
        b, c, unload = self.b, self.b.carrier, self.b.unload
        ex, ey = self.tx - x[:, None, :], self.ty - y[:, None, :]
        far = (ex * ex + ey * ey + self.z2).max(axis=1)
        dt, h = carrier_steps(x - self.px, y - self.py, self.h0, c)
        t = self.t0 + dt + unload
        worst = np.maximum(self.head, t + leg_times(np.sqrt(far), b.rover))
        dt, h = carrier_steps(self.nx - x, self.ny - y, h, c)
        t1 = t + dt
        worst = np.maximum(worst, self.done1 + (t1 - self.arrive1))
        dt = self.hop12
        if c.turn_rate is not None:
            turn = (self.h12 - h) % _TAU
            dt = dt + np.minimum(turn, _TAU - turn) / c.turn_rate
        if not self.all_moving12:
            dt = np.where(self.moving12, dt, 0.0)
        worst = np.maximum(worst, self.tail2 + (t1 + unload + dt - self.arrive2))
        worst[far > self.d2max] = np.inf
        return worst


def search_class(builder: PathBuilder, route: Route, ks: Sequence[int], tol: float) -> dict[int, Point2]:
    """Where each stop of ``ks`` (no two sharing a hop) goes: a jump to its cluster's centre or the
    point nearest the carrier's line when that is faster, then a compass search of all stops at
    once, each with every other stop fixed: 8 directions at the step and at half of it, the best
    of the 16, the step halved (quartered when none helps) down to ``tol``; the last ``HANDOFF``
    stops still moving finish one by one (``compass_search`` on ``stop_cost``). Returns the stops
    that moved."""
    sc = StopClass(builder, route, ks)
    m = len(ks)
    x = np.array([route.positions[k][0] for k in ks])
    y = np.array([route.positions[k][1] for k in ks])
    best = np.full(m, route.makespan)
    jumps = []
    for k in ks:
        prev = builder.start if k == 0 else route.positions[k - 1]
        jumps.append((route.geos[k].center, max_range_point(prev, route.geos[k], route.positions[k + 1])))
    jx = np.array([[p[0] for p in two] for two in jumps])
    jy = np.array([[p[1] for p in two] for two in jumps])
    t = sc.cost(jx, jy)  # both jumps at once, taken in the scalar polish's order
    for j in range(2):
        ok = t[:, j] < best - 1e-9
        x, y, best = np.where(ok, jx[:, j], x), np.where(ok, jy[:, j], y), np.where(ok, t[:, j], best)
    step = np.full(m, max(builder.inst.d / 4, 0.05))
    live = step > tol
    rows = np.arange(m)
    while live.any():  # every row is scored (cheaper than selecting the live ones); the live move
        # the compass points at the step and at half of it, in one call
        radii = np.repeat(np.stack([step, step / 2], axis=1), 8, axis=1)
        cx = x[:, None] + radii * _DX2
        cy = y[:, None] + radii * _DY2
        t = sc.cost(cx, cy)
        t[:, 8:][step / 2 <= tol] = np.inf  # below the last step
        j = t.argmin(axis=1)
        tj = t[rows, j]
        ok = live & (tj < best - 1e-9)
        x = np.where(ok, cx[rows, j], x)
        y = np.where(ok, cy[rows, j], y)
        best = np.where(ok, tj, best)
        step = np.where(ok, np.where(j >= 8, step / 2, step), np.where(live, step / 4, step))
        live &= step > tol
        if 0 < live.sum() <= HANDOFF:  # a few stops still moving: one by one (cheaper)
            for i in np.flatnonzero(live).tolist():
                k = ks[i]
                x[i], y[i], best[i] = compass_search(stop_cost(builder, route, k), float(x[i]), float(y[i]),
                                                     float(best[i]), float(step[i]), tol)
            break
    out: dict[int, Point2] = {}
    for i, k in enumerate(ks):
        q = (float(x[i]), float(y[i]))
        if q != route.positions[k]:
            out[k] = q
    return out
