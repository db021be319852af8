"""Reach regions of rovers to collect and the meeting points inside them (dissertation ch. 5.4).

A rover hovering at height z with d_collect metres of flight left must fly to the carrier and land
on it, so the ground points it can reach form the disc of radius sqrt(d_collect² − z²) around its
ground position (in 2D, z = 0, the disc of radius d_collect — the "circle of maximum travel
distance" O_D of the chapter). A cluster of rovers can be collected at one stop exactly when the
discs of all its rovers intersect (eq. 5.12); the intersection I_β is convex.

Everything here is plane geometry on those discs:

* ``Region``: the intersection of a cluster's discs, its *power centre* (the point minimising
  max_i |c − g_i|² − ρ_i², found with the power-weighted enclosing ball of ch. 3.4; it lies in
  I_β whenever I_β is non-empty, so it doubles as the feasibility test of Algorithm 5.1's
  GET_INTERPTS), the intersection points of the circles that bound I_β (Fig. 5.6's black dots)
  and its *time centre* (the point of I_β whose farthest rover, in 3D, is nearest).
* projections onto I_β and the points of I_β nearest a segment (eq. 5.13–5.16), computed exactly
  from the fact that a nearest point of an intersection of discs lies either on one circle or at
  an intersection point of two.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from planners.core.geometry import CircleCache, enclosing_ball
from planners.core.native import kernels

Point2 = tuple[float, float]

# Points within this many metres outside a disc count as inside (flights keep RANGE_MARGIN spare).
INSIDE_TOL = 1e-9
MEMO_SIZE = 256  # projections and line points a region remembers (then it starts afresh)


@dataclass(slots=True)
class Region:
    """The common reach region I_β of a cluster (eq. 5.12)."""

    members: tuple[int, ...]
    _discs: list[tuple[float, float, float]] = field(repr=False)  # (x, y, ρ): ground position, reach radius
    _rows: list[tuple[float, float, float]] = field(repr=False)  # (x, y, z²)
    center: Point2  # power centre: in I_β when I_β is non-empty
    depth: float  # min_i (ρ_i − |center − g_i|) ≥ 0 when feasible
    feasible: bool
    _arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    _vertices: np.ndarray | None = field(default=None, repr=False)
    _time_center: Point2 | None = field(default=None, repr=False)
    _vertex_list: list[Point2] | None = field(default=None, repr=False)
    _memo: dict[tuple[float, ...], Point2] = field(default_factory=dict, repr=False, compare=False)
    _time_circles: CircleCache | None = field(default=None, repr=False, compare=False)
    _near: tuple[tuple[int, ...], ...] = field(default=(), repr=False, compare=False)  # neighbours' members
    # (x, y, (ρ + INSIDE_TOL)²) of every member: ``contains``'s test at the default tolerance
    _limits: list[tuple[float, float, float]] | None = field(default=None, repr=False, compare=False)
    # per disc (by id): the crossings of its circle with the others' that lie in I_β, with the other
    # disc (``_vertex_projection``)
    _rims: dict[int, list[tuple[Point2, tuple[float, float, float]]]] = field(
        default_factory=dict, repr=False, compare=False)

    @property
    def rows(self) -> list[tuple[float, float, float]]:
        """(x, y, z²) of every member, for fast pure-Python loops."""
        return self._rows

    def _numpy(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._arrays is None:
            self._arrays = (np.array([(x, y) for x, y, _ in self._discs], dtype=float).reshape(-1, 2),
                            np.array([r for _, _, r in self._discs], dtype=float),
                            np.array([z2 for _, _, z2 in self._rows], dtype=float))
        return self._arrays

    @property
    def centers(self) -> np.ndarray:
        """(k, 2) ground positions g_i (numpy; made when first asked for)."""
        return self._numpy()[0]

    @property
    def radii(self) -> np.ndarray:
        """(k,) reach radii ρ_i."""
        return self._numpy()[1]

    @property
    def heights2(self) -> np.ndarray:
        """(k,) z_i²."""
        return self._numpy()[2]

    def contains(self, p: Sequence[float], tol: float = INSIDE_TOL) -> bool:
        x, y = p[0], p[1]
        if tol != INSIDE_TOL:
            return not any((x - cx) ** 2 + (y - cy) ** 2 > (r + tol) ** 2 for cx, cy, r in self._discs)
        for cx, cy, lim in self._limits or self._make_limits():
            if (x - cx) ** 2 + (y - cy) ** 2 > lim:
                return False
        return True

    def _make_limits(self) -> list[tuple[float, float, float]]:
        """``_limits``: the same (ρ + tol)² as computed per call, made once."""
        self._limits = [(cx, cy, (r + INSIDE_TOL) ** 2) for cx, cy, r in self._discs]
        return self._limits

    @property
    def discs(self) -> list[tuple[float, float, float]]:
        """(x, y, ρ) of every member."""
        return self._discs

    def farthest_flight(self, p: Sequence[float]) -> float:
        """Longest 3D flight of a member to ground point ``p``: the cluster's last arrival there."""
        return _farthest(self._rows, p)

    @property
    def vertices(self) -> np.ndarray:
        """Intersection points of the cluster's circles that lie in I_β (Fig. 5.6, GET_INTERPTS)."""
        if self._vertices is None:
            self._vertices = np.array(self.vertex_list, dtype=float).reshape(-1, 2)
        return self._vertices

    @property
    def time_center(self) -> Point2:
        """The point of I_β whose farthest rover is nearest (minimises the cluster's last arrival).

        Without the range constraint it is the power-weighted enclosing circle of the ground
        positions with weights z² (ch. 3.4); when that point lies outside I_β, its projection.
        The circle comes from ``_time_circles`` when the region has them (a collection's instance
        shares them between its regions: derived from the neighbouring clusters' ``_near``).
        """
        if self._time_center is None:
            ws = [z2 for _, _, z2 in self.rows]
            if self._time_circles is not None:
                cx, cy, _ = self._time_circles.get(self.members, ws, self._near)
            else:
                ball = enclosing_ball([(x, y) for x, y, _ in self.rows], ws)
                cx, cy = ball.center
            c = (float(cx), float(cy))
            self._time_center = c if self.contains(c) else self.project(c)
        return self._time_center

    @property
    def vertex_list(self) -> list[Point2]:
        """``vertices`` as a list (computed in plain Python: clusters are small)."""
        if self._vertex_list is None:
            self._vertex_list = _disc_vertices(self.discs)
        return self._vertex_list

    def project(self, p: Sequence[float]) -> Point2:
        """Nearest point of I_β to ``p``: ``p`` itself, its projection onto one disc, or a vertex
        (a nearest point of an intersection of discs has one or two active constraints).
        Remembered per point: the cluster searches project the same stops again and again."""
        key = (float(p[0]), float(p[1]))
        got = self._memo.get(key)
        if got is None:
            if len(self._memo) > MEMO_SIZE:
                self._memo.clear()
            got = self._memo[key] = self._project(key[0], key[1])
        return got

    def _project(self, x: float, y: float) -> Point2:
        """``project_discs``, then, when the nearest point is no circle's, the vertices."""
        got = _project_discs(self._discs, self._limits or self._make_limits(), x, y)
        if type(got) is tuple:
            return got
        vertex = self._vertex_projection(x, y, self._discs[got])  # type: ignore[index]
        if vertex is not None:
            return vertex
        best, best_d = self.center, math.inf  # numerically empty region: the power centre
        for q in self.vertex_list:
            d = math.hypot(q[0] - x, q[1] - y)
            if d < best_d:
                best, best_d = q, d
        return best

    def _vertex_projection(self, x: float, y: float, disc: tuple[float, float, float]) -> Point2 | None:
        """The nearest point of I_β to (x, y) when it is a vertex on the circle ``disc`` (the one
        (x, y) violates most): ``vertex_on_rim`` of that circle's crossings, remembered per circle."""
        rim = self._rims.get(id(disc))
        if rim is None:  # the circle's crossings with every other that lie in I_β: the same for every (x, y)
            rim = self._rims[id(disc)] = self._rim(disc)
        return _vertex_on_rim(rim, disc, x, y)

    def _rim(self, disc: tuple[float, float, float]) -> list[tuple[Point2, tuple[float, float, float]]]:
        """``rim`` of ``disc`` in this region."""
        return _rim(disc, self._discs, self._limits or self._make_limits())

    def clip_segment(self, a: Point2, b: Point2) -> tuple[float, float] | None:
        """Parameters [s0, s1] ⊂ [0, 1] of the part of segment a → b inside I_β, or None."""
        return _clip(self._discs, a, b)

    def nearest_to_segment(self, a: Point2, b: Point2) -> list[Point2]:
        """Eq. 5.13–5.16: the point(s) of I_β nearest the carrier's line a → b.

        If the segment crosses I_β, where it enters and leaves (any point between is as near; the
        entry is the carrier's earliest chance). Otherwise the nearest point of I_β to the segment
        (eq. 5.13 when the foot lies inside the segment, eq. 5.16 beyond its ends): a projection of
        an end point, a circle's point nearest the line, or a vertex.
        """
        seg = self.clip_segment(a, b)
        if seg is not None:
            s0, s1 = seg
            p0 = (a[0] + s0 * (b[0] - a[0]), a[1] + s0 * (b[1] - a[1]))
            p1 = (a[0] + s1 * (b[0] - a[0]), a[1] + s1 * (b[1] - a[1]))
            return [p0, p1]
        cands: list[Point2] = [self.project(a), self.project(b)]
        dx, dy = b[0] - a[0], b[1] - a[1]
        length = math.hypot(dx, dy)
        if length > 1e-9:
            nx, ny = -dy / length, dx / length  # unit normal of the line (eq. 5.13's objective)
            discs = self._discs
            pts = []
            for cx, cy, r in discs:  # each centre stepped toward the line by its radius
                step = -r if (cx - a[0]) * nx + (cy - a[1]) * ny > 0 else r
                pts.append((cx + step * nx, cy + step * ny))
            pts += self.vertex_list
            pts = [p for p in pts if _inside_all_discs(p, discs)]
            if pts:
                d = [_seg_dist(p, a, b) for p in pts]
                cands.append(pts[min(range(len(d)), key=d.__getitem__)])
        return [min(cands, key=lambda p: _seg_dist(p, a, b))]

    def line_point(self, prev: Point2, nxt: Point2 | None) -> Point2:
        """A quick eq. 5.13: where the carrier's line prev → next enters I_β, else the projection of
        the line's point nearest the time centre."""
        if nxt is None:
            return self.project(prev)
        key = (prev[0], prev[1], nxt[0], nxt[1])
        got = self._memo.get(key)
        if got is None:
            if len(self._memo) > MEMO_SIZE:
                self._memo.clear()
            got = self._memo[key] = self._line_point(prev, nxt)
        return got

    def _line_point(self, prev: Point2, nxt: Point2) -> Point2:
        seg = self.clip_segment(prev, nxt)
        if seg is not None:
            s0 = seg[0]
            return (prev[0] + s0 * (nxt[0] - prev[0]), prev[1] + s0 * (nxt[1] - prev[1]))
        c = self.time_center
        dx, dy = nxt[0] - prev[0], nxt[1] - prev[1]
        qa = dx * dx + dy * dy
        s = 0.0 if qa < 1e-18 else min(max(((c[0] - prev[0]) * dx + (c[1] - prev[1]) * dy) / qa, 0.0), 1.0)
        return self.project((prev[0] + s * dx, prev[1] + s * dy))

    def quick_candidates(self, prev: Point2, nxt: Point2 | None) -> list[Point2]:
        """A small candidate set for the clustering search: time centre, the point nearest the
        previous stop, and the carrier's line point."""
        pts = [self.time_center, self.project(prev)]
        if nxt is not None:
            pts.append(self.line_point(prev, nxt))
        return pts

    def candidates(self, prev: Point2, nxt: Point2 | None) -> list[Point2]:
        """The fast planner's candidate meeting points (ch. 5.4, Fig. 5.6): the circles'
        intersection points, the points nearest the carrier's line prev → next (eq. 5.13–5.16),
        the points nearest prev and next, the power centre and the time centre."""
        pts: list[Point2] = [self.center, self.time_center, self.project(prev)]
        if nxt is not None:
            pts.append(self.project(nxt))
            pts += self.nearest_to_segment(prev, nxt)
        pts += self.vertex_list
        return pts


def vertex_on_rim(rim: Sequence[tuple[Point2, tuple[float, float, float]]], disc: tuple[float, float, float],
                  x: float, y: float) -> Point2 | None:
    """The vertex of the circle ``disc`` nearest to (x, y), among its crossings ``rim`` (``rim``),
    when it is the nearest point of I_β: the optimality condition holds there (x − v lies in the
    cone of the two active circles' outward normals). Else None, and the caller scans every vertex.
    O(k²) only through the inside test, no vertex list built."""
    xm, ym, rm = disc
    hypot = math.hypot
    best: Point2 | None = None
    other = disc
    least = math.inf
    for q, d2 in rim:  # the nearest vertex (ties: the first crossing)
        dq = hypot(q[0] - x, q[1] - y)
        if dq < least:
            best, other, least = q, d2, dq
    if best is None:
        return None
    vx, vy = best
    a1x, a1y = vx - xm, vy - ym
    a2x, a2y = vx - other[0], vy - other[1]
    det = a1x * a2y - a1y * a2x
    if abs(det) < 1e-12 * max(1.0, math.hypot(a1x, a1y) * math.hypot(a2x, a2y)):
        return None
    px, py = x - vx, y - vy
    lam1 = (px * a2y - py * a2x) / det
    lam2 = (a1x * py - a1y * px) / det
    return best if lam1 >= -1e-9 and lam2 >= -1e-9 else None


def project_discs(discs: Sequence[tuple[float, float, float]], limits: Sequence[tuple[float, float, float]],
                  x: float, y: float) -> Point2 | int:
    """The nearest point of the discs' intersection to (x, y) when it is (x, y) itself or lies on one
    circle; else the index of the disc (x, y) violates most (the nearest point is then a vertex:
    ``Region._vertex_projection``). ``limits``: (x, y, (ρ + INSIDE_TOL)²) per disc.

    The intersection lies inside every disc, so the distance to it is at least the largest distance
    to one disc, and a disc's nearest point that lies in the intersection is its nearest point:
    only the discs (x, y) violates most can give it (O(k))."""
    if len(discs) == 1:
        cx, cy, r = discs[0]
        n = math.hypot(x - cx, y - cy)
        if n <= r:
            return (x, y)
        return (cx + (x - cx) * r / n, cy + (y - cy) * r / n)
    hypot = math.hypot
    out = []  # (−violation, disc index): sorted, the most violated first, ties in the discs' order
    for i, (cx, cy, r) in enumerate(discs):
        n = hypot(x - cx, y - cy)
        if n > r + INSIDE_TOL:
            out.append((r - n, i, n))
    if not out:
        return (x, y)
    if len(out) > 1:
        out.sort()
    least = out[0][0]
    for neg, i, n in out:
        if -neg < -least - 1e-9:
            break
        cx, cy, r = discs[i]
        qx, qy = cx + (x - cx) * r / n, cy + (y - cy) * r / n
        for gx, gy, lim in limits:  # (``Region.contains``, written out)
            if (qx - gx) ** 2 + (qy - gy) ** 2 > lim:
                break
        else:
            return (qx, qy)
    return out[0][1]


def rim(disc: tuple[float, float, float], discs: Sequence[tuple[float, float, float]],
        limits: Sequence[tuple[float, float, float]]) -> list[tuple[Point2, tuple[float, float, float]]]:
    """The crossings of ``disc``'s circle with every other of ``discs`` that lie in their intersection
    (``limits``: ``Region.contains``'s test, written out), each with the other disc, in the discs'
    order (``Region._vertex_projection``)."""
    out = []
    for d2 in discs:
        if d2 is disc:
            continue
        for q in _pair_points(disc, d2):
            x, y = q
            for cx, cy, lim in limits:
                if (x - cx) ** 2 + (y - cy) ** 2 > lim:
                    break
            else:
                out.append((q, d2))
    return out


def clip_segment(discs: Sequence[tuple[float, float, float]], a: Sequence[float],
                 b: Sequence[float]) -> tuple[float, float] | None:
    """Parameters [s0, s1] ⊂ [0, 1] of the part of segment a → b inside every disc, or None."""
    ax, ay = a[0], a[1]
    dx, dy = b[0] - ax, b[1] - ay
    qa = dx * dx + dy * dy
    lo, hi = 0.0, 1.0
    sqrt = math.sqrt
    for cx, cy, r in discs:
        ex, ey = ax - cx, ay - cy
        qc = ex * ex + ey * ey - r * r
        if qa < 1e-18:
            if qc > 0:
                return None
            continue
        qb = 2.0 * (dx * ex + dy * ey)
        disc = qb * qb - 4.0 * qa * qc
        if disc < 0:
            return None
        sq = sqrt(disc)
        s0 = (-qb - sq) / (2.0 * qa)
        if s0 > lo:  # (max and min, written out)
            lo = s0
        s1 = (-qb + sq) / (2.0 * qa)
        if s1 < hi:
            hi = s1
        if lo > hi:
            return None
    return lo, hi


def farthest_flight(rows: Sequence[tuple[float, float, float]], p: Sequence[float]) -> float:
    """The longest flight from a row (x, y, z²) to ground point ``p`` (``Region.farthest_flight``)."""
    x, y = p[0], p[1]
    worst = 0.0
    for gx, gy, z2 in rows:
        d2 = (x - gx) * (x - gx) + (y - gy) * (y - gy) + z2
        if d2 > worst:
            worst = d2
    return math.sqrt(worst)




def _seg_dist(p: Sequence[float], a: Point2, b: Point2) -> float:
    dx, dy = b[0] - a[0], b[1] - a[1]
    qa = dx * dx + dy * dy
    s = 0.0 if qa < 1e-18 else min(max(((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / qa, 0.0), 1.0)
    return math.hypot(p[0] - a[0] - s * dx, p[1] - a[1] - s * dy)


# relative: a squared distance this far from the squared limit decides ``_inside_all_discs``
INSIDE_CERTAIN = 1e-13


def _inside_all_discs(p: Point2, discs: Sequence[tuple[float, float, float]],
                      tol: float = INSIDE_TOL) -> bool:
    """Whether numpy's hypot(p − g) ≤ ρ + tol for every disc (the test ``nearest_to_segment``
    made with numpy arrays, the same answer). The squared distance decides it unless it lies
    within ``INSIDE_CERTAIN`` of (ρ + tol)² (hypot and the sum of squares are both within a few
    ulps of the distance); there numpy's hypot itself decides."""
    x, y = p
    for cx, cy, r in discs:
        dx, dy = x - cx, y - cy
        lim = r + tol
        d2, lim2 = dx * dx + dy * dy, lim * lim
        if d2 <= lim2 * (1.0 - INSIDE_CERTAIN):
            continue
        if d2 >= lim2 * (1.0 + INSIDE_CERTAIN) or not float(np.hypot(dx, dy)) <= lim:
            return False
    return True


def circle_vertices(centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Pairwise intersection points of the circles (g_i, ρ_i) that lie inside every disc."""
    discs = [(float(x), float(y), float(r))
             for (x, y), r in zip(centers.tolist(), radii.tolist(), strict=True)]
    return np.array(disc_vertices(discs), dtype=float).reshape(-1, 2)


def _pair_points(d1: tuple[float, float, float], d2: tuple[float, float, float]) -> tuple[Point2, ...]:
    """The two intersection points of two circles (x, y, ρ), or () when they do not cross."""
    xi, yi, ri = d1
    xj, yj, rj = d2
    dx, dy = xj - xi, yj - yi
    dist = math.hypot(dx, dy)
    if not (dist > 1e-12 and dist <= ri + rj + INSIDE_TOL and dist >= abs(ri - rj) - INSIDE_TOL):
        return ()
    a = (ri * ri - rj * rj + dist * dist) / (2.0 * dist)
    h2 = ri * ri - a * a
    h = math.sqrt(0.0 if 0.0 > h2 else h2)  # (max(h2, 0.0), written out)
    ux, uy = dx / dist, dy / dist
    bx, by = xi + a * ux, yi + a * uy
    px, py = -uy * h, ux * h
    return (bx + px, by + py), (bx - px, by - py)


def disc_vertices(discs: Sequence[tuple[float, float, float]]) -> list[Point2]:
    """``circle_vertices`` of discs (x, y, ρ) in plain Python, the same arithmetic: every pair's two
    intersection points (all pairs' first points, then all pairs' second points) that lie inside
    every disc. For the few discs of a cluster this is several times faster than numpy."""
    plus: list[Point2] = []
    minus: list[Point2] = []
    k = len(discs)
    for i in range(k):
        for j in range(i + 1, k):
            pts = _pair_points(discs[i], discs[j])
            if pts:
                plus.append(pts[0])
                minus.append(pts[1])
    out = []
    for q in plus + minus:
        x, y = q
        for cx, cy, r in discs:
            if math.hypot(x - cx, y - cy) > r + INSIDE_TOL:
                break
        else:
            out.append(q)
    return out


DiscLists = tuple[Sequence[Sequence[float]], Sequence[float], Sequence[float]]  # ground xy, ρ, z²
# per rover: the (x, y, ρ) disc, the (x, y, z²) row and ρ², plain floats (a collection's instance keeps them)
RoverRows = tuple[Sequence[tuple[float, float, float]], Sequence[tuple[float, float, float]], Sequence[float]]


def rover_rows(lists: DiscLists) -> RoverRows:
    """The discs, rows and squared radii of ``make_region``'s ``rows`` from ground xy, ρ and z² lists."""
    pts, rad, h2 = lists
    discs = [(float(x), float(y), float(q)) for (x, y), q in zip(pts, rad, strict=True)]
    rows = [(float(x), float(y), float(w)) for (x, y), w in zip(pts, h2, strict=True)]
    return discs, rows, [q * q for _, _, q in discs]


def make_region(members: Sequence[int], ground: np.ndarray, radii: np.ndarray,
                heights2: np.ndarray, lists: DiscLists | None = None,
                circles: tuple[CircleCache, CircleCache] | None = None,
                near: tuple[tuple[int, ...], ...] = (), rows: RoverRows | None = None) -> Region:
    """I_β of ``members`` with its power centre (the feasibility test of Algorithm 5.1).

    The power centre minimises max_i |c − g_i|² − ρ_i²; shifting every weight by W = max ρ² keeps
    them non-negative for the enclosing-ball routine without moving the minimiser. I_β is
    non-empty exactly when the minimum is ≤ 0, and then the centre lies in I_β. ``lists``: the
    same ground positions, radii and z² as Python lists, or ``rows`` (``rover_rows``: every
    rover's disc and row made once; a collection's instance keeps them), so that the cluster's
    discs are read without numpy. ``circles``: the instance's enclosing circles
    for the power centre and the time centre (the same balls, derived from those of the clusters
    ``near``, sorted memberships one member away, when exact); ``members`` must then be sorted.
    """
    key = tuple(members)
    if rows is None:
        if lists is None:
            idx = list(key)
            lists = (ground[idx].tolist(), radii[idx].tolist(), heights2[idx].tolist())
            rows = rover_rows(lists)
        else:
            rows = rover_rows(([lists[0][i] for i in key], [lists[1][i] for i in key],
                               [lists[2][i] for i in key]))
        key_rows: Sequence[int] = range(len(key))
    else:
        key_rows = key
    all_discs, all_rows, all_r2 = rows
    discs = [all_discs[i] for i in key_rows]
    reg_rows = [all_rows[i] for i in key_rows]
    if len(key) == 1:
        reg = Region(key, discs, reg_rows, (discs[0][0], discs[0][1]), discs[0][2], True)
    else:
        r2 = [all_r2[i] for i in key_rows]
        top = max(r2)
        ws = [top - q for q in r2]  # ≥ 0: q ≤ top, and rounding keeps the sign of a difference
        if circles is not None:
            px, py, _ = circles[0].get(key, ws, near)
        else:
            ball = enclosing_ball([(x, y) for x, y, _ in discs], ws)
            px, py = float(ball.center[0]), float(ball.center[1])
        hypot = math.hypot
        depth = min([q - hypot(x - px, y - py) for x, y, q in discs])
        reg = Region(key, discs, reg_rows, (px, py), depth, depth >= -INSIDE_TOL)
    if circles is not None:
        reg._time_circles, reg._near = circles[1], near
    return reg


# the compiled twins when they are built (planners.core.native): the same floats
_farthest = farthest_flight if kernels is None else kernels.farthest_flight
_project_discs = project_discs if kernels is None else kernels.project_discs
_rim = rim if kernels is None else kernels.rim
_clip = clip_segment if kernels is None else kernels.clip_segment
_vertex_on_rim = vertex_on_rim if kernels is None else kernels.vertex_on_rim
_disc_vertices = disc_vertices if kernels is None else kernels.disc_vertices
