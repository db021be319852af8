"""Carrier routes over points: nearest neighbour + 2-opt (the TSP heuristics of ch. 4.6.2)."""

from __future__ import annotations

import itertools
import math
from collections import deque

import numpy as np

from planners.core.native import kernels


def two_opt_route(points: np.ndarray, start: np.ndarray, initial: list[int] | None = None,
                  long_tours: bool = False) -> list[int]:
    """Open tour from ``start`` through every point: nearest neighbour (or ``initial``), then 2-opt
    to a local optimum. Returns the visiting order as indices into ``points``.

    The 2-opt is exhaustive (every reversal; the baselines of ch. 4.6.2 / 5.5.2). With
    ``long_tours``, tours of more than ``SMALL_TOUR`` points use the neighbour-list 2-opt instead
    (``_two_opt_neighbours``: near-linear, the planners' re-sequencing of long routes)."""
    n = len(points)
    if n == 0:
        return []
    nodes = np.vstack([start[None, :], points])
    if long_tours and n > SMALL_TOUR:
        return _two_opt_neighbours(nodes, initial)
    dmat = np.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=2)
    if initial is not None:
        route = [0] + [i + 1 for i in initial]
    else:
        route = nearest_neighbour(dmat)
    if n <= SMALL_TOUR:
        if n >= ROWS_FROM:
            return _two_opt_rows(dmat, route)
        if kernels is not None:  # the compiled twin: the same tour
            return kernels.two_opt_small(dmat, route)
        return _two_opt_small(dmat.tolist(), route)
    # 2-opt on the open path: reverse route[i..j]; the start stays first, the end is free.
    path = np.array(route)
    improved = True
    while improved:
        improved = False
        for i in range(1, n):
            a, b = path[i - 1], path[i]
            js = np.arange(i + 1, n + 1)
            c = path[js]
            d_next = np.append(dmat[c[:-1], path[js[:-1] + 1]], 0.0)  # edge after j (none at the end)
            after = np.append(dmat[b, path[js[:-1] + 1]], 0.0)
            gain = dmat[a, b] + d_next - dmat[a, c] - after
            k = int(np.argmax(gain))
            if gain[k] > 1e-9:
                j = int(js[k])
                path[i: j + 1] = path[i: j + 1][::-1].copy()
                improved = True
    return [int(v) - 1 for v in path[1:]]


SMALL_TOUR = 80  # points: up to this many, the 2-opt in plain Python over the distance matrix
# points: from this many on, the small tours' 2-opt scores whole rows with numpy (the same tours); the
# plain loop measured 2-3x faster at every size up to SMALL_TOUR (30 random and nearest-neighbour
# tours per size, 24-80 points), so none of them does at present
ROWS_FROM = SMALL_TOUR + 1
NEIGHBOURS = 10  # candidate new edges per node of the long tours' neighbour-list 2-opt


def nearest_neighbour(dmat: np.ndarray) -> list[int]:
    """Greedy open tour over a distance matrix, starting at node 0."""
    n = len(dmat) - 1
    route = [0]
    left = np.ones(n + 1, dtype=bool)
    left[0] = False
    for _ in range(n):
        row = np.where(left, dmat[route[-1]], np.inf)
        nxt = int(np.argmin(row))
        route.append(nxt)
        left[nxt] = False
    return route


def _two_opt_small(d: list[list[float]], route: list[int]) -> list[int]:
    """The same 2-opt in plain Python: faster than numpy for the short tours of clusters. The
    path's edge lengths are kept in a list beside it (``edge[k]``: path[k] → path[k + 1], the
    same matrix entries), so a gain reads one entry fewer; the gains are the same floats, summed
    in the same order, so the reversals and the tour are those of the matrix 2-opt
    (``_two_opt_rows``)."""
    path = route[:]
    n = len(path) - 1
    edge = [d[path[k]][path[k + 1]] for k in range(n)]
    improved = True
    while improved:
        improved = False
        for i in range(1, n):
            b = path[i]
            dab = edge[i - 1]
            da, db = d[path[i - 1]], d[b]
            for j in range(i + 1, n):  # reversing path[i..j]: edges a→b and c→e become a→c and b→e
                e = path[j + 1]
                if dab + edge[j] - da[path[j]] - db[e] > 1e-9:
                    path[i: j + 1] = path[i: j + 1][::-1]
                    edge[i: j] = edge[i: j][::-1]  # (the matrix is symmetric)
                    b = path[i]
                    dab = edge[i - 1] = da[b]
                    db = d[b]
                    edge[j] = d[path[j]][e]
                    improved = True
            if dab - da[path[n]] > 1e-9:  # j = n: the path's end reversed (no edge after it)
                path[i:] = path[i:][::-1]
                edge[i: n] = edge[i: n][::-1]
                edge[i - 1] = da[path[i]]
                improved = True
    return [v - 1 for v in path[1:]]


def _two_opt_rows(dmat: np.ndarray, route: list[int]) -> list[int]:
    """``_two_opt_small`` with its gains held in a matrix (row i, column j: reversing path[i..j]),
    scanned in the same order (row by row, first improvement) and computed with the same
    floating-point operations, so it makes the same reversals and returns the same tour. A
    reversal of path[i..j] changes only rows i..j + 1 ahead of the scan; every sweep starts from
    the whole matrix again."""
    n = len(route) - 1
    if n < 2:
        return [v - 1 for v in route[1:]]
    path = np.array(route)
    ahead = ~np.tri(n + 1, n + 1, 0, dtype=bool)  # j > i
    ahead[0] = False  # the start stays first
    gain = np.full((n + 1, n + 1), -np.inf)
    flat = gain.ravel()
    edge = np.zeros(n + 1)  # edge[j] = d(path[j], path[j + 1]); none after the end
    after = np.zeros((n + 1, n + 1))  # after[i, j] = d(path[i], path[j + 1]); 0 at j = n

    def score(lo: int, hi: int) -> None:  # rows lo..hi-1 of the current path
        edge[:n] = dmat[path[:-1], path[1:]]
        sub = dmat[path[lo - 1:hi]][:, path]
        e = after[:hi - lo]
        e[:, :n] = sub[1:, 1:]
        # the plain loop's dab + d[c][e] - da[c] - db[e], term by term in the same order
        rows = edge[lo - 1:hi - 1, None] + edge[None, :] - sub[:-1] - e
        gain[lo:hi] = np.where(ahead[lo:hi], rows, -np.inf)

    score(1, n + 1)
    improved, at = False, 0
    while True:
        hit = np.flatnonzero(flat[at:] > 1e-9)
        if hit.size == 0:
            if not improved:
                break
            improved, at = False, 0
            score(1, n + 1)
            continue
        k = at + int(hit[0])
        i, j = divmod(k, n + 1)
        path[i:j + 1] = path[i:j + 1][::-1].copy()
        score(i, min(j + 2, n + 1))
        improved, at = True, k + 1
    return [int(v) - 1 for v in path[1:]]


def _nearest_neighbour_tree(xy: np.ndarray, near: list[list[int]]) -> list[int]:
    """Greedy open tour from node 0 (``nearest_neighbour``) with the k-nearest lists ``near``;
    when every listed neighbour is visited, the nearest unvisited node by a scan of those left."""
    n = len(xy)
    left = np.ones(n, dtype=bool)
    left[0] = False
    route = [0]
    cur = 0
    for _ in range(n - 1):
        nxt = next((y for y in near[cur] if left[y]), -1)
        if nxt < 0:
            rest = np.flatnonzero(left)
            gap = xy[rest] - xy[cur]
            nxt = int(rest[np.argmin(np.einsum("ij,ij->i", gap, gap))])
        route.append(nxt)
        left[nxt] = False
        cur = nxt
    return route


def _two_opt_neighbours(nodes: np.ndarray, initial: list[int] | None, k: int = NEIGHBOURS) -> list[int]:
    """2-opt on a long open path (node 0 first, the end free) with neighbour lists and don't-look
    bits: an improving reversal adds an edge shorter than one it removes, so only new edges from
    a node to its ``k`` nearest are tried, from both ends of the removed edge; a node whose edges
    did not change is not looked at again (until a last sweep finds none). O(n·k) per sweep instead
    of O(n²); the neighbours
    come from a k-d tree (scipy.spatial.cKDTree), the first tour from the nearest neighbours."""
    from scipy.spatial import cKDTree  # on demand: only long tours need it

    n = len(nodes) - 1
    k = min(k, n)
    near = cKDTree(nodes).query(nodes, k + 1)[1].tolist()  # (includes the node itself)
    path = [0] + [i + 1 for i in initial] if initial is not None else _nearest_neighbour_tree(nodes, near)
    xy = nodes.tolist()
    pos = [0] * (n + 1)
    for i, v in enumerate(path):
        pos[v] = i
    dist = math.dist  # the same as math.hypot of the differences, bit for bit
    near_d = [[dist(xy[x], xy[y]) for y in ys] for x, ys in enumerate(near)]
    # the nearest of a node's later neighbours: past it, neither of its edges can be shortened
    rest = [list(itertools.accumulate(ds[::-1], min))[::-1] for ds in near_d]

    def gain(i: int, j: int) -> float:
        """Shortening when path[i..j] is reversed (1 <= i < j <= n)."""
        a, b, c = xy[path[i - 1]], xy[path[i]], xy[path[j]]
        g = dist(a, b) - dist(a, c)
        if j < n:
            e = xy[path[j + 1]]
            g += dist(c, e) - dist(b, e)
        return g

    def improve(x: int) -> tuple[int, int] | None:
        u = pos[x]
        nx = path[u + 1] if u < n else None
        px = path[u - 1] if u > 0 else None
        d_next = dist(xy[x], xy[nx]) if nx is not None else 0.0
        d_prev = dist(xy[x], xy[px]) if px is not None else 0.0
        for y, dxy, lower in zip(near[x], near_d[x], rest[x], strict=True):
            if lower >= d_next and lower >= d_prev and nx is not None:
                break
            if y == x:
                continue
            w = pos[y]
            if dxy < d_next:  # new edge x–y instead of x → next(x)
                ij = (u + 1, w) if w > u + 1 else (w + 1, u) if w < u else None
                if ij is not None and gain(*ij) > 1e-9:
                    return ij
            if dxy < d_prev:  # new edge y–x instead of prev(x) → x
                ij = (w, u - 1) if 1 <= w < u - 1 else (u, w - 1) if w > u + 1 else None
                if ij is not None and gain(*ij) > 1e-9:
                    return ij
            if nx is None and w < u - 1 and gain(w + 1, u) > 1e-9:  # x last: y–x, the path's end reversed
                return w + 1, u
        return None

    queue = deque(path[1:])
    queued = [True] * (n + 1)
    queued[0] = False
    while queue:
        x = queue.popleft()
        queued[x] = False
        ij = improve(x)
        if ij is None:
            if not queue:  # a reversal flips the segment inside it, which changes its nodes' moves:
                queue.extend(v for v in path[1:] if improve(v) is not None)  # sweep once more
                for v in queue:
                    queued[v] = True
            continue
        i, j = ij
        ends = [path[i - 1], path[i], path[j]] + ([path[j + 1]] if j < n else [])
        path[i:j + 1] = path[i:j + 1][::-1]
        for t in range(i, j + 1):
            pos[path[t]] = t
        for v in ends:
            if v and not queued[v]:
                queued[v] = True
                queue.append(v)
    return [v - 1 for v in path[1:]]
