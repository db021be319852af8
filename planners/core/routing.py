"""Carrier routes over points: nearest neighbour + 2-opt (the TSP heuristics of ch. 4.6.2)."""

from __future__ import annotations

import numpy as np


def two_opt_route(points: np.ndarray, start: np.ndarray, initial: list[int] | None = None) -> list[int]:
    """Open tour from ``start`` through every point: nearest neighbour (or ``initial``), then 2-opt
    to a local optimum. Returns the visiting order as indices into ``points``."""
    n = len(points)
    if n == 0:
        return []
    nodes = np.vstack([start[None, :], points])
    dmat = np.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=2)
    if initial is not None:
        route = [0] + [i + 1 for i in initial]
    else:
        route = nearest_neighbour(dmat)
    if n <= 80:
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
    """The same 2-opt in plain Python: faster than numpy for the short tours of clusters."""
    path = route[:]
    n = len(path) - 1
    improved = True
    while improved:
        improved = False
        for i in range(1, n):
            a, b = path[i - 1], path[i]
            dab = d[a][b]
            da, db = d[a], d[b]
            for j in range(i + 1, n + 1):
                c = path[j]
                if j < n:
                    e = path[j + 1]
                    gain = dab + d[c][e] - da[c] - db[e]
                else:
                    gain = dab - da[c]
                if gain > 1e-9:
                    path[i: j + 1] = path[i: j + 1][::-1]
                    a, b = path[i - 1], path[i]
                    dab, da, db = d[a][b], d[a], d[b]
                    improved = True
    return [v - 1 for v in path[1:]]
