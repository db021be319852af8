"""Probabilistic roadmap for deployment and collection among obstacles (dissertation ch. 6.2–6.4).

Obstacles are ground polygons of unlimited height (walls): a carrier or rover segment is
collision-free when its ground projection does not touch any obstacle. The roadmap is an
undirected graph over collision-free ground points:

* global PRM (eq. 6.5–6.6): ℵ₁ = √(w·h)·ξ₁ + ξ₂ nodes (the carrier start and the tasks count
  among them, the rest uniform collision-free samples), edges up to δ = max(d_deploy, (w+h)/2·φ)
  that do not touch an obstacle;
* local PRM (eq. 6.7): ℵ_add = √(w_ROI·h_ROI)·ξ₃ + ξ₄ extra nodes in a cluster's region of
  interest, edges up to d_deploy;
* shortest paths by Dijkstra (scipy.sparse.csgraph; A* with a zero heuristic) and path
  shortcutting (Algorithm 6.2).

Deterministic for a seed: sampling uses one ``numpy.random.Generator``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import shapely
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree
from shapely import STRtree
from shapely.geometry import Polygon

from planners.core.problem import PlanningError, Point2, Polygon2, RoadmapParams

Bounds = tuple[Point2, Point2]

MAX_NODES = 6000  # a roadmap larger than this is refused (PlanningError) rather than planned for minutes
MAX_EDGES = 120_000  # the same for edges (a long edge radius makes the roadmap a complete graph)
SIGHT_PAIRS = 500_000  # node pairs whose line of sight the shortcut remembers


def _node_count(value: float, what: str) -> int:
    if not math.isfinite(value) or value > MAX_NODES:
        raise PlanningError(f"the {what} roadmap would have {value:.3g} nodes, more than {MAX_NODES}; "
                            "lower the roadmap parameters (xi1..xi4) or the workspace bounds")
    return int(round(value))


class Workspace:
    """The ground workspace: bounds and obstacle polygons, with vectorised collision tests."""

    def __init__(self, obstacles: Sequence[Polygon2], bounds: Bounds) -> None:
        self.polygons = [_valid(Polygon(p)) for p in obstacles]
        self.tree = STRtree(self.polygons) if self.polygons else None
        self._prepared = np.asarray(self.polygons, dtype=object)  # for the exact tests after the tree
        shapely.prepare(self._prepared)
        (x0, y0), (x1, y1) = bounds
        if not (x1 > x0 and y1 > y0):
            raise PlanningError(f"bounds {list(bounds[0])}..{list(bounds[1])} enclose no area")
        self.bounds: Bounds = ((float(x0), float(y0)), (float(x1), float(y1)))

    @property
    def width(self) -> float:
        return self.bounds[1][0] - self.bounds[0][0]

    @property
    def height(self) -> float:
        return self.bounds[1][1] - self.bounds[0][1]

    def _hit(self, geoms: np.ndarray) -> np.ndarray:
        """Indices of ``geoms`` that touch an obstacle: the tree's boxes first, then the exact test
        against the prepared polygons (about twice as fast as the tree's own predicate, which
        prepares every query geometry)."""
        assert self.tree is not None
        gi, oi = self.tree.query(geoms)
        return gi[shapely.intersects(self._prepared[oi], geoms[gi])]

    def points_free(self, xy: np.ndarray) -> np.ndarray:
        """Mask of points outside every obstacle (on an obstacle's boundary counts as inside)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        free = np.ones(len(xy), dtype=bool)
        if self.tree is not None and len(xy):
            free[self._hit(shapely.points(xy))] = False
        return free

    def segments_free(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Mask of segments a[i] → b[i] whose ground projection touches no obstacle."""
        a = np.asarray(a, dtype=float).reshape(-1, 2)
        b = np.asarray(b, dtype=float).reshape(-1, 2)
        free = np.ones(len(a), dtype=bool)
        if self.tree is None or not len(a):
            return free
        same = np.all(np.abs(a - b) < 1e-12, axis=1)
        coords = np.stack([a, b], axis=1)
        coords[same, 1] += 1e-9  # a zero-length segment is tested as (almost) its point
        free[self._hit(shapely.linestrings(coords))] = False
        return free

    def segment_free(self, p: Sequence[float], q: Sequence[float]) -> bool:
        return bool(self.segments_free(np.array([p[:2]]), np.array([q[:2]]))[0])

    def fans_free(self, lo: Point2, hi: Point2, ends: np.ndarray) -> bool:
        """No obstacle touches the convex hull of the rectangle lo..hi and any one of ``ends``: then
        every segment from a point of the rectangle to one of the ends is collision-free."""
        if self.tree is None:
            return True
        corners = [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]
        hulls = shapely.convex_hull(shapely.multipoints([[*corners, (float(e[0]), float(e[1]))]
                                                         for e in np.asarray(ends).reshape(-1, 2)]))
        return len(self._hit(np.atleast_1d(hulls))) == 0

    def rect_free(self, lo: Point2, hi: Point2) -> bool:
        """No obstacle touches the rectangle lo..hi."""
        if self.tree is None:
            return True
        return len(self._hit(np.atleast_1d(shapely.box(lo[0], lo[1], hi[0], hi[1])))) == 0

    def inside_bounds(self, xy: np.ndarray) -> np.ndarray:
        (x0, y0), (x1, y1) = self.bounds
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)

    def sample(self, rng: np.random.Generator, count: int, lo: Point2 | None = None,
               hi: Point2 | None = None) -> np.ndarray:
        """``count`` uniform collision-free points in the rectangle lo..hi (default: the bounds).

        Samples inside an obstacle are discarded and drawn again (ch. 6.3.1); a rectangle that is
        (almost) all obstacle yields fewer points rather than looping forever.
        """
        lo = lo or self.bounds[0]
        hi = hi or self.bounds[1]
        out: list[np.ndarray] = []
        need = count
        for _ in range(50):
            if need <= 0:
                break
            batch = rng.uniform(lo, hi, size=(max(2 * need, 8), 2))
            batch = batch[self.points_free(batch)][:need]
            out.append(batch)
            need -= len(batch)
        return np.concatenate(out) if out else np.zeros((0, 2))


def _valid(poly: Polygon) -> Polygon:
    return poly if poly.is_valid else poly.buffer(0)


class Roadmap:
    """An undirected graph over collision-free ground points; nodes are never removed."""

    def __init__(self, workspace: Workspace, points: np.ndarray, radius: float) -> None:
        self.ws = workspace
        self.delta = radius  # the connection radius of the global roadmap (eq. 6.6)
        self.xy = np.zeros((0, 2))
        self._i = np.zeros(0, dtype=np.int64)
        self._j = np.zeros(0, dtype=np.int64)
        self._csr: csr_matrix | None = None
        self._sp: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._sight: dict[tuple[int, int], bool] = {}
        self.global_nodes = 0
        self.global_edges = 0
        self.add(points, radius)

    @property
    def n_nodes(self) -> int:
        return len(self.xy)

    @property
    def n_edges(self) -> int:
        return len(self._i)

    def edges(self) -> np.ndarray:
        """(E, 2) node index pairs (for drawing)."""
        return np.stack([self._i, self._j], axis=1)

    def add(self, points: np.ndarray, radius: float) -> np.ndarray:
        """Add nodes and link each to every node within ``radius`` by a collision-free edge."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        first = len(self.xy)
        self.xy = np.concatenate([self.xy, pts])
        new = np.arange(first, len(self.xy))
        if not len(pts):
            return new
        tree = cKDTree(self.xy)
        if len(self.xy) > MAX_NODES:
            raise PlanningError(f"the roadmap would have {len(self.xy)} nodes, more than {MAX_NODES}; "
                                "lower the roadmap parameters (xi1..xi4) or the workspace bounds")
        near = int(np.sum(tree.query_ball_point(pts, radius, return_length=True)))
        if self.n_edges + near // 2 > MAX_EDGES:  # about the candidate edges: refuse before building them
            raise PlanningError(f"the roadmap would have about {self.n_edges + near // 2} edges (up to "
                                f"{radius:.3g} m long), more than {MAX_EDGES}; lower rovers.deploy_range, "
                                "the roadmap parameters (xi1..xi4, phi) or the workspace bounds")
        pairs = []
        for k, nbrs in zip(new, tree.query_ball_point(pts, radius), strict=True):
            nb = np.asarray(nbrs, dtype=np.int64)
            nb = nb[(nb < k)]  # old nodes and earlier new nodes: every pair once
            if len(nb):
                pairs.append(np.stack([np.full(len(nb), k), nb], axis=1))
        if pairs:
            pr = np.concatenate(pairs)
            ok = self.ws.segments_free(self.xy[pr[:, 0]], self.xy[pr[:, 1]])
            pr = pr[ok]
            self._i = np.concatenate([self._i, pr[:, 0]])
            self._j = np.concatenate([self._j, pr[:, 1]])
        self._csr = None
        self._sp.clear()
        return new

    def link(self, new: np.ndarray, to: Sequence[int], radius: float, beyond: float) -> None:
        """Also link nodes ``new`` (just added with edges up to ``beyond``) to the nodes ``to``
        between ``beyond`` and ``radius`` away, by collision-free edges."""
        src, dst = np.asarray(new, dtype=np.int64), np.asarray(to, dtype=np.int64)
        if not len(src) or not len(dst):
            return
        a, b = np.repeat(src, len(dst)), np.tile(dst, len(src))
        d = np.hypot(*(self.xy[a] - self.xy[b]).T)
        keep = (d > beyond) & (d <= radius) & (a != b)
        a, b = a[keep], b[keep]
        ok = self.ws.segments_free(self.xy[a], self.xy[b])
        self._i = np.concatenate([self._i, a[ok]])
        self._j = np.concatenate([self._j, b[ok]])
        self._csr = None
        self._sp.clear()

    def graph(self) -> csr_matrix:
        if self._csr is None:
            w = np.hypot(*(self.xy[self._i] - self.xy[self._j]).T)
            w = np.maximum(w, 1e-12)  # coincident nodes stay connected (csgraph drops zero weights)
            n = len(self.xy)
            rows = np.concatenate([self._i, self._j])
            cols = np.concatenate([self._j, self._i])
            self._csr = csr_matrix((np.concatenate([w, w]), (rows, cols)), shape=(n, n))
        return self._csr

    def shortest(self, source: int) -> tuple[np.ndarray, np.ndarray]:
        """Path lengths and predecessors from ``source`` to every node (cached until the graph grows)."""
        got = self._sp.get(source)
        if got is None:
            d, pred = dijkstra(self.graph(), directed=True, indices=source, return_predecessors=True)
            got = (d, pred)
            self._sp[source] = got
        return got

    def has_tree(self, source: int) -> bool:
        """Whether the shortest paths from ``source`` are at hand (``shortest`` costs nothing)."""
        return source in self._sp

    def distances(self, sources: Sequence[int], limit: float = np.inf) -> np.ndarray:
        """(len(sources), N) shortest path lengths, inf beyond ``limit``."""
        if not len(sources):
            return np.zeros((0, self.n_nodes))
        return np.atleast_2d(dijkstra(self.graph(), directed=True, indices=list(sources), limit=limit))

    def path(self, source: int, target: int) -> list[int]:
        """Node indices of a shortest path source → target (PlanningError if none)."""
        d, pred = self.shortest(source)
        if not math.isfinite(d[target]):
            raise PlanningError("no path on the roadmap")
        out = [target]
        while out[-1] != source:
            out.append(int(pred[out[-1]]))
        return out[::-1]

    def shortcut(self, nodes: Sequence[int]) -> list[Point2]:
        """Algorithm 6.2: from each kept vertex jump to the farthest later vertex in plain sight."""
        idx = [int(v) for v in nodes]
        pts = self.xy[idx]
        n = len(pts)
        if n <= 2:  # line 2: a sub-route of two nodes is already smooth
            return [(float(p[0]), float(p[1])) for p in pts]
        kept = [0]
        j = 0
        while j < n - 1:
            ks = np.arange(n - 1, j, -1)  # k = n : -1 : j+1
            free = self.visible(idx[j], [idx[k] for k in ks])
            k = int(ks[int(np.argmax(free))]) if free.any() else j + 1
            kept.append(k)
            j = k
        return [(float(pts[k][0]), float(pts[k][1])) for k in kept]

    def visible(self, a: int, others: Sequence[int]) -> np.ndarray:
        """Mask of the nodes ``others`` in plain sight of node ``a`` (collision-free segments).
        Nodes never move, so each pair is tested once (a bounded cache, kept as the roadmap grows)."""
        out = np.zeros(len(others), dtype=bool)
        todo = []
        for m, b in enumerate(others):
            got = self._sight.get((a, b) if a < b else (b, a))
            if got is None:
                todo.append(m)
            else:
                out[m] = got
        if todo:
            bs = [others[m] for m in todo]
            free = self.ws.segments_free(np.repeat(self.xy[a:a + 1], len(bs), axis=0), self.xy[bs])
            if len(self._sight) + len(bs) > SIGHT_PAIRS:
                self._sight.clear()
            for m, b, f in zip(todo, bs, free, strict=True):
                out[m] = f
                self._sight[(a, b) if a < b else (b, a)] = bool(f)
        return out

    def smoothed_path(self, source: int, target: int) -> list[Point2]:
        """A shortest roadmap path, shortcut (GetSmoothedSubRoute)."""
        return self.shortcut(self.path(source, target))


def global_prm(workspace: Workspace, fixed: np.ndarray, d_deploy: float, params: RoadmapParams,
               rng: np.random.Generator) -> Roadmap:
    """Global PRM: the fixed nodes (carrier start, tasks) plus samples up to ℵ₁ nodes in all."""
    w, h = workspace.width, workspace.height
    count = _node_count(math.sqrt(w * h) * params.xi1 + params.xi2, "global")  # eq. 6.5
    delta = max(d_deploy, (w + h) / 2.0 * params.phi)  # eq. 6.6
    samples = workspace.sample(rng, max(count - len(fixed), 0))
    rm = Roadmap(workspace, np.concatenate([np.asarray(fixed, dtype=float).reshape(-1, 2), samples]), delta)
    rm.global_nodes, rm.global_edges = rm.n_nodes, rm.n_edges
    return rm


def densify(rm: Roadmap, rng: np.random.Generator, params: RoadmapParams, nodes: Sequence[int],
            rounds: int = 4) -> None:
    """Half of ℵ₁ more global samples per round while some of ``nodes`` are cut off from node 0
    (a sparse roadmap may miss a narrow door)."""
    w, h = rm.ws.width, rm.ws.height
    count = _node_count((math.sqrt(w * h) * params.xi1 + params.xi2) / 2, "global")
    for _ in range(rounds):
        if np.all(np.isfinite(rm.shortest(0)[0][list(nodes)])):
            return
        rm.add(rm.ws.sample(rng, count), rm.delta)


def disc_region(centers: np.ndarray, radii: np.ndarray) -> tuple[Point2, Point2] | None:
    """Bounding rectangle of the intersection of discs (Fig. 6.4's red rectangle), None if empty."""
    lo_x = float(np.max(centers[:, 0] - radii))
    hi_x = float(np.min(centers[:, 0] + radii))
    lo_y = float(np.max(centers[:, 1] - radii))
    hi_y = float(np.min(centers[:, 1] + radii))
    if lo_x > hi_x or lo_y > hi_y:
        return None
    point = radii <= 1e-9
    if point.any():  # a disc of radius zero: the region is that point or nothing
        p = centers[int(np.argmax(point))]
        if np.all(np.hypot(*(centers - p).T) <= radii + 1e-9):
            return (float(p[0]), float(p[1])), (float(p[0]), float(p[1]))
        return None
    discs = (shapely.Point(float(c[0]), float(c[1])).buffer(float(r), quad_segs=32)
             for c, r in zip(centers, radii, strict=True))
    region = next(discs)  # there is one at least: np.max above raised on none
    for disc in discs:
        region = region.intersection(disc)
        if region.is_empty:
            return None
    x0, y0, x1, y1 = region.bounds
    return (x0, y0), (x1, y1)


def local_prm(rm: Roadmap, rng: np.random.Generator, lo: Point2, hi: Point2, d_deploy: float,
              params: RoadmapParams) -> np.ndarray:
    """Local PRM (eq. 6.7) in the rectangle lo..hi, edges up to d_deploy; the new node indices."""
    (bx0, by0), (bx1, by1) = rm.ws.bounds  # the region of interest inside the workspace
    lo = (max(lo[0], bx0), max(lo[1], by0))
    hi = (min(hi[0], bx1), min(hi[1], by1))
    w, h = hi[0] - lo[0], hi[1] - lo[1]
    if w < 0 or h < 0:
        return np.zeros(0, dtype=np.int64)
    count = _node_count(math.sqrt(max(w * h, 0.0)) * params.xi3 + params.xi4, "local")
    pts = rm.ws.sample(rng, count, lo, hi)
    return rm.add(pts, d_deploy)
