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

import numpy as np

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


@functools.lru_cache(maxsize=4096)
def _shuffled(n: int, seed: int) -> tuple[int, ...]:
    """The visiting order of Welzl's algorithm: ``range(n)`` shuffled by ``random.Random(seed)``."""
    order = list(range(n))
    random.Random(seed).shuffle(order)
    return tuple(order)


def enclosing_circle(xs: Sequence[float], ys: Sequence[float], ws: Sequence[float],
                     seed: int = 0) -> tuple[float, float, float]:
    """``enclosing_ball`` of the plane points (xs[i], ys[i]) with power weights ws[i], as
    (centre x, centre y, radius): the same visiting order, tolerance and arithmetic as the general
    Welzl loop (``solve``), unrolled for the plane without closures or Ball objects in the loop
    (the planners compute thousands of these per plan)."""
    n = len(xs)
    if n == 1:
        return float(xs[0]), float(ys[0]), math.sqrt(max(float(ws[0]), 0.0))
    order = _shuffled(n, seed)
    x = [float(xs[i]) for i in order]
    y = [float(ys[i]) for i in order]
    w = [float(ws[i]) for i in order]
    eps = _REL_EPS * max(1.0, max(max(x), max(y)), -min(min(x), min(y)), math.sqrt(max(w)))
    cx, cy, r = x[0], y[0], math.sqrt(max(w[0], 0.0))
    lim = (r + eps) ** 2
    for i in range(1, n):
        if (cx - x[i]) ** 2 + (cy - y[i]) ** 2 + w[i] <= lim:
            continue
        cx, cy, r = x[i], y[i], math.sqrt(max(w[i], 0.0))
        lim = (r + eps) ** 2
        for j in range(i):
            if (cx - x[j]) ** 2 + (cy - y[j]) ** 2 + w[j] <= lim:
                continue
            cx, cy, r = _circle_two(x, y, w, i, j)
            lim = (r + eps) ** 2
            for k in range(j):
                if (cx - x[k]) ** 2 + (cy - y[k]) ** 2 + w[k] > lim:
                    cx, cy, r = _circle_three(x, y, w, i, j, k)
                    lim = (r + eps) ** 2
    return cx, cy, r


def _circle_two(x: list[float], y: list[float], w: list[float], i: int, j: int) -> tuple[float, float, float]:
    """The smallest circle with points i and j on its boundary (``_ball_2d`` written out)."""
    x0, y0, w0 = x[i], y[i], w[i]
    ux, uy = x[j] - x0, y[j] - y0
    n = ux * ux + uy * uy
    if n < 1e-24:
        return _as_tuple(_ball_on_boundary([(x0, y0), (x[j], y[j])], [w0, w[j]]))
    lam = (n + w[j] - w0) / (2.0 * n)
    c = (x0 + lam * ux, y0 + lam * uy)
    value = max(math.dist(c, (x0, y0)) ** 2 + w0, math.dist(c, (x[j], y[j])) ** 2 + w[j])
    return c[0], c[1], math.sqrt(max(value, 0.0))


def _circle_three(x: list[float], y: list[float], w: list[float], i: int, j: int,
                  k: int) -> tuple[float, float, float]:
    """The circle with points i, j and k on its boundary (``_ball_2d`` written out)."""
    x0, y0, w0 = x[i], y[i], w[i]
    u1x, u1y = x[j] - x0, y[j] - y0
    u2x, u2y = x[k] - x0, y[k] - y0
    b1 = u1x * u1x + u1y * u1y + w[j] - w0
    b2 = u2x * u2x + u2y * u2y + w[k] - w0
    det = u1x * u2y - u1y * u2x
    if abs(det) < 1e-12 * max(1.0, (u1x * u1x + u1y * u1y) * (u2x * u2x + u2y * u2y)) ** 0.5:
        return _as_tuple(_ball_on_boundary([(x0, y0), (x[j], y[j]), (x[k], y[k])], [w0, w[j], w[k]]))
    c = (x0 + (b1 * u2y - b2 * u1y) / (2.0 * det), y0 + (u1x * b2 - u2x * b1) / (2.0 * det))
    value = max(math.dist(c, (x0, y0)) ** 2 + w0, math.dist(c, (x[j], y[j])) ** 2 + w[j],
                math.dist(c, (x[k], y[k])) ** 2 + w[k])
    return c[0], c[1], math.sqrt(max(value, 0.0))


def _as_tuple(ball: Ball) -> tuple[float, float, float]:
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
