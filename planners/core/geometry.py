"""Geometry for the planners: minimum enclosing circle/sphere (ch. 3.4) and small helpers.

The enclosing ball is Welzl's algorithm (iterative move-to-front form) generalised to *power
weights*: it minimises ``max_i |c - p_i|² + w_i`` over centres ``c``. With all weights zero it
is the minimum enclosing circle (2D points) or sphere (3D points) of eq. 3.1; with 2D ground
points and ``w_i = z_i²`` it is the ground point whose farthest 3D task is nearest — the best
place on the ground to deploy a cluster of tasks at heights.
"""

from __future__ import annotations

import functools
import math
import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from planners.core.native import kernels

_REL_EPS = 1e-9


@dataclass(frozen=True)
class Ball:
    center: tuple[float, ...]
    radius: float  # sqrt of the minimised maximum power distance

    def contains(self, p: Sequence[float], weight: float = 0.0, eps: float = 1e-7) -> bool:
        return _power(self.center, p, weight) <= (self.radius + eps) ** 2


def _power(c: Sequence[float], p: Sequence[float], w: float) -> float:
    return math.dist(c, p) ** 2 + w


def _ball_on_boundary(pts: list[tuple[float, ...]], ws: list[float]) -> Ball:
    """Smallest-value centre with every given point on the boundary (equal power distance).

    Minimises |c - p0|² + w0 subject to |c - pj|² + wj = |c - p0|² + w0: a linear system in
    the affine hull of the points (eq. 3.5–3.6 and 3.10–3.11 are its unweighted 2D/3D forms).
    Degenerate sets (collinear, duplicate) are solved in the least-squares sense.
    """
    if len(pts) == 1:
        return Ball(tuple(pts[0]), math.sqrt(max(ws[0], 0.0)))
    if len(pts[0]) == 2 and len(pts) <= 3:  # closed forms for the planners' hot path
        fast = _ball_2d(pts, ws)
        if fast is not None:
            return fast
    p0, w0 = np.asarray(pts[0], dtype=float), ws[0]
    u = np.asarray(pts[1:], dtype=float) - p0
    b = np.einsum("ij,ij->i", u, u) + np.asarray(ws[1:]) - w0
    gram = 2.0 * (u @ u.T)
    lam, *_ = np.linalg.lstsq(gram, b, rcond=None)
    c = p0 + lam @ u
    value = max(_power(c, q, w) for q, w in zip(pts, ws, strict=True))
    return Ball(tuple(float(x) for x in c), math.sqrt(max(value, 0.0)))


def _ball_2d(pts: list[tuple[float, ...]], ws: list[float]) -> Ball | None:
    (x0, y0), w0 = pts[0], ws[0]
    u1x, u1y = pts[1][0] - x0, pts[1][1] - y0
    b1 = u1x * u1x + u1y * u1y + ws[1] - w0
    if len(pts) == 2:
        n = u1x * u1x + u1y * u1y
        if n < 1e-24:
            return None
        lam = b1 / (2.0 * n)
        c = (x0 + lam * u1x, y0 + lam * u1y)
    else:
        u2x, u2y = pts[2][0] - x0, pts[2][1] - y0
        b2 = u2x * u2x + u2y * u2y + ws[2] - w0
        det = u1x * u2y - u1y * u2x  # solve 2 u_j · (c − p0) = b_j directly
        if abs(det) < 1e-12 * max(1.0, (u1x * u1x + u1y * u1y) * (u2x * u2x + u2y * u2y)) ** 0.5:
            return None
        dx = (b1 * u2y - b2 * u1y) / (2.0 * det)
        dy = (u1x * b2 - u2x * b1) / (2.0 * det)
        c = (x0 + dx, y0 + dy)
    value = max(_power(c, q, w) for q, w in zip(pts, ws, strict=True))
    return Ball(c, math.sqrt(max(value, 0.0)))


def enclosing_ball(points: Sequence[Sequence[float]], weights: Sequence[float] | None = None,
                   seed: int = 0) -> Ball:
    """Minimum enclosing circle/sphere (optionally power-weighted) by Welzl's algorithm.

    Expected linear time; exact for 1, 2, 3+ points, collinear and duplicate points.
    """
    if not points:
        raise ValueError("enclosing_ball of no points")
    if len(points) > 1 and len(points[0]) == 2:
        return _enclosing_circle(points, weights, seed)
    pts = [tuple(map(float, p)) for p in points]
    ws = [0.0] * len(pts) if weights is None else [float(w) for w in weights]
    dim = len(pts[0])
    order = _shuffled(len(pts), seed)
    pts = [pts[i] for i in order]
    ws = [ws[i] for i in order]
    scale = max(1.0, max(max(p) for p in pts), -min(min(p) for p in pts), math.sqrt(max(ws)))
    eps = _REL_EPS * scale

    def outside(ball: Ball, k: int) -> bool:
        return not ball.contains(pts[k], ws[k], eps)

    def solve(fixed: list[int], upto: int, depth: int) -> Ball:
        # Smallest ball of pts[:upto] with pts[fixed] on its boundary.
        ball = _ball_on_boundary([pts[i] for i in fixed], [ws[i] for i in fixed]) if fixed else None
        for k in range(upto):
            if ball is None or outside(ball, k):
                if depth == dim:  # d+1 boundary points determine the ball
                    ball = _ball_on_boundary([pts[i] for i in [*fixed, k]], [ws[i] for i in [*fixed, k]])
                else:
                    ball = solve([*fixed, k], k, depth + 1)
        assert ball is not None
        return ball

    if len(pts) == 1:
        return _ball_on_boundary([pts[0]], [ws[0]])
    return solve([], len(pts), 0)


def _enclosing_circle(points: Sequence[Sequence[float]], weights: Sequence[float] | None, seed: int) -> Ball:
    """``enclosing_ball`` of two or more points in the plane (``enclosing_circle``)."""
    ws = [0.0] * len(points) if weights is None else weights
    cx, cy, r = enclosing_circle([p[0] for p in points], [p[1] for p in points], ws, seed)
    return Ball((cx, cy), r)


def enclosing_circle(xs: Sequence[float], ys: Sequence[float], ws: Sequence[float],
                     seed: int = 0) -> tuple[float, float, float]:
    """``enclosing_ball`` of the plane points (xs[i], ys[i]) with power weights ws[i], as
    (centre x, centre y, radius): the same visiting order, tolerance and arithmetic as the general
    Welzl loop (``solve``), unrolled for the plane (``_welzl_2d``)."""
    n = len(xs)
    if n == 1:
        return float(xs[0]), float(ys[0]), math.sqrt(max(float(ws[0]), 0.0))
    order = _shuffled(n, seed)
    vx, vy, vw = [float(xs[i]) for i in order], [float(ys[i]) for i in order], [float(ws[i]) for i in order]
    if kernels is not None:  # the compiled twin: the same circle
        return kernels.welzl_2d(vx, vy, vw, _boundary_circle)[0]
    return _welzl_2d(vx, vy, vw)[0]


@functools.lru_cache(maxsize=4096)
def _shuffled(n: int, seed: int) -> tuple[int, ...]:
    """The visiting order of Welzl's algorithm: ``range(n)`` shuffled by ``random.Random(seed)``."""
    order = list(range(n))
    random.Random(seed).shuffle(order)
    return tuple(order)


@functools.lru_cache(maxsize=4096)
def _visit_rank(n: int, seed: int) -> tuple[int, ...]:
    """When Welzl's algorithm visits each of ``n`` points: the inverse of ``_shuffled(n, seed)``."""
    rank = [0] * n
    for k, i in enumerate(_shuffled(n, seed)):
        rank[i] = k
    return tuple(rank)


Circle = tuple[float, float, float]  # centre x, y and radius of a circle in the hot loops


# The hot loops below write builtins' max(a, b) out as ``b if b > a else a`` (and min likewise):
# the same element, the first of equals (so the same sign of a zero), without the call.


def _one(xs: list[float], ys: list[float], ws: list[float], i: int) -> Circle:
    w = ws[i]
    return xs[i], ys[i], math.sqrt(0.0 if 0.0 > w else w)


def _two(xs: list[float], ys: list[float], ws: list[float], i: int, j: int) -> Circle:
    """The smallest circle with points i and j on its boundary (``_ball_2d``'s closed form)."""
    x0, y0, w0 = xs[i], ys[i], ws[i]
    x1, y1, w1 = xs[j], ys[j], ws[j]
    ux, uy = x1 - x0, y1 - y0
    n = ux * ux + uy * uy
    if n < 1e-24:
        return _boundary_circle([(x0, y0), (x1, y1)], [w0, w1])
    lam = (n + w1 - w0) / (2.0 * n)
    cx, cy = x0 + lam * ux, y0 + lam * uy
    hypot = math.hypot  # (math.dist of two points is hypot of their difference, bit for bit)
    value = hypot(cx - x0, cy - y0) ** 2 + w0
    v1 = hypot(cx - x1, cy - y1) ** 2 + w1
    if v1 > value:
        value = v1
    return cx, cy, math.sqrt(0.0 if 0.0 > value else value)


def _three(xs: list[float], ys: list[float], ws: list[float], i: int, j: int, k: int) -> Circle:
    """The circle with points i, j and k on its boundary (``_ball_2d``'s closed form)."""
    x0, y0, w0 = xs[i], ys[i], ws[i]
    x1, y1, w1 = xs[j], ys[j], ws[j]
    x2, y2, w2 = xs[k], ys[k], ws[k]
    u1x, u1y = x1 - x0, y1 - y0
    u2x, u2y = x2 - x0, y2 - y0
    b1 = u1x * u1x + u1y * u1y + w1 - w0
    b2 = u2x * u2x + u2y * u2y + w2 - w0
    det = u1x * u2y - u1y * u2x
    size = (u1x * u1x + u1y * u1y) * (u2x * u2x + u2y * u2y)
    if abs(det) < 1e-12 * (size if size > 1.0 else 1.0) ** 0.5:
        return _boundary_circle([(x0, y0), (x1, y1), (x2, y2)], [w0, w1, w2])
    cx, cy = x0 + (b1 * u2y - b2 * u1y) / (2.0 * det), y0 + (u1x * b2 - u2x * b1) / (2.0 * det)
    hypot = math.hypot
    value = hypot(cx - x0, cy - y0) ** 2 + w0
    v1 = hypot(cx - x1, cy - y1) ** 2 + w1
    if v1 > value:
        value = v1
    v2 = hypot(cx - x2, cy - y2) ** 2 + w2
    if v2 > value:
        value = v2
    return cx, cy, math.sqrt(0.0 if 0.0 > value else value)


def _tolerance(xs: list[float], ys: list[float], ws: list[float]) -> float:
    """Welzl's inside tolerance: ``_REL_EPS`` times the size of the coordinates and weights."""
    hx, hy, lx, ly = max(xs), max(ys), min(xs), min(ys)
    size = 1.0
    for v in (hy if hy > hx else hx, -(ly if ly < lx else lx), math.sqrt(max(ws))):
        if v > size:
            size = v
    return _REL_EPS * size


def _welzl_2d(xs: list[float], ys: list[float], ws: list[float]) -> tuple[Circle, tuple[int, ...]]:
    """The same three nested loops as ``solve`` for the plane, over the points in their visiting
    order, unrolled for speed: balls are (x, y, radius) tuples and the closed forms of ``_ball_2d``
    are written out (the planners compute thousands of these per plan). Also returns the points
    the last circle was built on (its support), latest visited first."""
    eps = _tolerance(xs, ys, ws)
    cx, cy, r = _one(xs, ys, ws, 0)
    lim = (r + eps) ** 2  # a point is inside the current circle when its power is at most this
    sup: tuple[int, ...] = (0,)
    for i in range(1, len(xs)):
        if (cx - xs[i]) ** 2 + (cy - ys[i]) ** 2 + ws[i] <= lim:
            continue
        cx, cy, r = _one(xs, ys, ws, i)
        lim, sup = (r + eps) ** 2, (i,)
        for j in range(i):
            if (cx - xs[j]) ** 2 + (cy - ys[j]) ** 2 + ws[j] <= lim:
                continue
            cx, cy, r = _two(xs, ys, ws, i, j)
            lim, sup = (r + eps) ** 2, (i, j)
            for k in range(j):
                if (cx - xs[k]) ** 2 + (cy - ys[k]) ** 2 + ws[k] > lim:
                    cx, cy, r = _three(xs, ys, ws, i, j, k)
                    lim, sup = (r + eps) ** 2, (i, j, k)
    return (cx, cy, r), sup


def _welzl_through(xs: list[float], ys: list[float], ws: list[float], a: int,
                   first: Sequence[int]) -> tuple[int, ...]:
    """The support of the smallest circle of all points with point ``a`` on its boundary (Welzl's
    two inner loops; the points ``first`` are visited first). That is the enclosing circle when
    ``a`` lies outside the other points' circle."""
    eps = _tolerance(xs, ys, ws)
    rest = [*first, *(q for q in range(len(xs)) if q != a and q not in first)]
    cx, cy, r = _one(xs, ys, ws, a)
    sup: tuple[int, ...] = (a,)
    for jj, j in enumerate(rest):
        if (cx - xs[j]) ** 2 + (cy - ys[j]) ** 2 + ws[j] <= (r + eps) ** 2:
            continue
        cx, cy, r = _two(xs, ys, ws, a, j)
        sup = (a, j)
        for k in rest[:jj]:
            if (cx - xs[k]) ** 2 + (cy - ys[k]) ** 2 + ws[k] > (r + eps) ** 2:
                cx, cy, r = _three(xs, ys, ws, a, j, k)
                sup = (a, j, k)
    return sup


def _on_support(xs: list[float], ys: list[float], ws: list[float], sup: Sequence[int]) -> Circle:
    """The circle ``_welzl_2d`` ends with when it builds its last circle on the points ``sup`` (in
    visiting order): the same closed form on the same points in the same order, so the same bits."""
    s = sorted(sup, reverse=True)
    if len(s) == 1:
        return _one(xs, ys, ws, s[0])
    if len(s) == 2:
        return _two(xs, ys, ws, s[0], s[1])
    return _three(xs, ys, ws, s[0], s[1], s[2])


Members = tuple[int, ...]


class EnclosingCircles:
    """Power-weighted enclosing circles of subsets of one set of points in the plane, remembered
    by sorted membership; a new subset's circle is derived from a remembered neighbouring subset
    (the caller names it: one member more, fewer or exchanged) when that is exact (an incremental
    Welzl's algorithm), else computed afresh.

    A circle is its support's circle (the points on its boundary that hold it: at most three in
    general position). Adding a point that lies inside it, or removing a point that is not in the
    support, leaves the circle as it is; adding a point outside puts that point on the new
    circle's boundary (Welzl's lemma: two loops instead of three). The new circle is then built
    on its support by ``_on_support``, the closed form Welzl's algorithm ends with on the new
    subset (it ends on the same support), which gives ``enclosing_ball``'s bits.
    """

    def __init__(self, points: Sequence[Sequence[float]]) -> None:
        self._xs = [float(p[0]) for p in points]
        self._ys = [float(p[1]) for p in points]
        self._known: dict[Members, tuple[Circle, Members]] = {}  # subset → its circle and support

    def get(self, key: Members, weights: Sequence[float] | None = None,
            near: Sequence[Members] = ()) -> Circle:
        """``enclosing_ball`` of the points ``key`` (sorted, distinct indices) with these weights
        (one per member, in ``key``'s order; zero when None) as (centre x, centre y, radius): the
        same ball, bit for bit. ``near``: subsets (sorted) that may differ from ``key`` by a member,
        whose circles may be known."""
        got = self._known.get(key)
        if got is not None:
            return got[0]
        order = _shuffled(len(key), 0)
        visit = [key[q] for q in order]
        xs, ys = [self._xs[g] for g in visit], [self._ys[g] for g in visit]
        ws = [0.0] * len(key) if weights is None else [float(weights[q]) for q in order]
        found = self._derive(key, xs, ys, ws, near) if near and len(key) > 1 else None
        if found is None:
            circle, sup = _welzl_2d(xs, ys, ws)
            found = circle, tuple(visit[q] for q in sup)
        self._known[key] = found
        return found[0]

    def _derive(self, key: Members, xs: list[float], ys: list[float], ws: list[float],
                near: Sequence[Members]) -> tuple[Circle, Members] | None:
        """The circle of ``key`` (points in visiting order) from a known neighbour's support, or
        None when no neighbour gives it."""
        rank = _visit_rank(len(key), 0)
        members = set(key)
        outside: tuple[int, list[int]] | None = None  # an added point outside a neighbour's circle
        for other in near:
            entry = self._known.get(other) if -1 <= len(key) - len(other) <= 1 else None
            if entry is None:
                continue
            added = members.difference(other)
            if len(added) > 1 or len(other) - len(key) + len(added) > 1 or not members.issuperset(entry[1]):
                continue  # more than one member added or removed, or a support point removed
            support = entry[1]
            local = [rank[key.index(g)] for g in support]
            circle = _on_support(xs, ys, ws, local)
            if not added:
                return circle, support
            a = rank[key.index(added.pop())]
            cx, cy, r = circle
            margin = 2 * _REL_EPS * (1.0 + abs(cx) + abs(cy) + r)  # more than Welzl's tolerance
            power = (cx - xs[a]) ** 2 + (cy - ys[a]) ** 2 + ws[a]
            if r > margin and power < (r - margin) ** 2:
                return circle, support
            if outside is None and power > (r + margin) ** 2:
                outside = a, local
        if outside is None:
            return None
        sup = _welzl_through(xs, ys, ws, *outside)
        order = _shuffled(len(key), 0)
        return _on_support(xs, ys, ws, sup), tuple(key[order[q]] for q in sup)


class CircleCache(Protocol):
    """What ``enclosing_circles`` returns: ``EnclosingCircles`` or its compiled twin."""

    def get(self, key: Members, weights: Sequence[float] | None = None,
            near: Sequence[Members] = ()) -> Circle: ...


def enclosing_circles(points: Sequence[Sequence[float]]) -> CircleCache:
    """``EnclosingCircles`` of the points, or its compiled twin (``planners.core.native``: the same
    circles, float for float, falling back to ``_ball_on_boundary`` on the same degenerate points)."""
    if kernels is not None:
        circles: CircleCache = kernels.Circles(points, _boundary_circle, _shuffled)
        return circles
    return EnclosingCircles(points)


def _boundary_circle(pts: list[tuple[float, ...]], ws: list[float]) -> Circle:
    """``_ball_on_boundary`` as a circle tuple: the closed forms' way out of degenerate points."""
    ball = _ball_on_boundary(pts, ws)
    return ball.center[0], ball.center[1], ball.radius


def minimize_1d(f: Callable[[float], float], lo: float, hi: float, samples: int = 12,
                tol: float = 1e-6) -> tuple[float, float]:
    """Global-ish minimum of a 1D function: coarse sampling, then golden-section refinement."""
    if hi <= lo:
        return lo, f(lo)
    xs = [lo + (hi - lo) * i / samples for i in range(samples + 1)]
    vals = [f(x) for x in xs]
    i = min(range(len(xs)), key=vals.__getitem__)
    best_x, best_v = xs[i], vals[i]
    a, b = xs[max(i - 1, 0)], xs[min(i + 1, samples)]
    g = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tol * max(1.0, hi - lo):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    for x, v in ((c, fc), (d, fd)):
        if v < best_v:
            best_x, best_v = x, v
    return best_x, best_v


def find_root(f: Callable[[float], float], lo: float, hi: float, xtol: float = 1e-9,
              max_iter: int = 200) -> float:
    """A root of ``f`` in [lo, hi] where f(lo) and f(hi) have opposite signs (or one is 0).

    Regula falsi with the Illinois modification (superlinear on smooth functions; the bracket
    always shrinks); stops when the bracket is narrower than ``xtol``.
    """
    a, b = lo, hi
    fa, fb = f(a), f(b)
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    if fa * fb > 0:
        raise ValueError("find_root: f(lo) and f(hi) must have opposite signs")
    side = 0
    for _ in range(max_iter):
        if abs(b - a) <= xtol:
            break
        x = (a * fb - b * fa) / (fb - fa)
        if not min(a, b) < x < max(a, b):
            x = 0.5 * (a + b)
        fx = f(x)
        if fx == 0.0:
            return x
        if fx * fb > 0:
            b, fb = x, fx
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a, fa = x, fx
            if side == 1:
                fb *= 0.5
            side = 1
    return 0.5 * (a + b)


COMPASS = [(math.cos(a * math.pi / 4), math.sin(a * math.pi / 4)) for a in range(8)]


def compass_search(f: Callable[[float, float], float], x: float, y: float, best: float, step: float,
                   tol: float) -> tuple[float, float, float]:
    """Minimise ``f(x, y)`` from (x, y), whose value is ``best``, by a compass search: 8 directions,
    first improvement (the last successful direction tried first), halving the step down to
    ``tol``. Returns the point and its value; ``f`` may return inf where a point is infeasible."""
    first, back = 0, -1
    while step > tol:
        for i in range(8):
            j = (first + i) & 7
            if j == back:  # the point just left: its value is the previous best, no improvement
                continue
            dx, dy = COMPASS[j]
            cx, cy = x + step * dx, y + step * dy
            t = f(cx, cy)
            if t < best - 1e-9:
                best, x, y, first, back = t, cx, cy, j, (j + 4) & 7
                break
        else:
            step /= 2
            back = -1
    return x, y, best
