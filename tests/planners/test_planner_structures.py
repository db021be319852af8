"""The planners' fast data structures against brute force: the long tours'
neighbour-list 2-opt and its k-d tree nearest neighbour tour, the reach regions' vertices and
projections, and the routes' incremental re-timing (deployment and collection) against a
route timed from scratch."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planners.collect.instance import CollectInstance
from planners.collect.path import PathBuilder as CollectBuilder
from planners.collect.path import Route as CollectRoute
from planners.collect.reach import disc_vertices, make_region
from planners.core.problem import CarrierSpec, CollectProblem, CollectRover, DeployProblem, Motion, Task
from planners.core.routing import (
    _nearest_neighbour_tree,
    _two_opt_neighbours,
    _two_opt_rows,
    _two_opt_small,
    nearest_neighbour,
    two_opt_route,
)
from planners.deploy.cluster import DeployInstance
from planners.deploy.lee import lee_clusters
from planners.deploy.path import PathBuilder as DeployBuilder
from planners.deploy.path import Route as DeployRoute
from planners.deploy.polish import polish_long
from planners.deploy.stops import StopClass, search_class, stop_cost

CARRIER = CarrierSpec(max_speed=12.0, accel=4.0, turn_rate=2.5, unload_time=2.0, load_time=3.0)
ROVER = Motion(3.0)


# ------------------------------------------------------------------ tours

def _length(nodes: np.ndarray, path: list[int]) -> float:
    return float(sum(np.hypot(*(nodes[a] - nodes[b])) for a, b in zip(path, path[1:], strict=False)))


@pytest.mark.parametrize("seed", range(6))
def test_tree_nearest_neighbour_tour_equals_the_matrix_one(seed: int) -> None:
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    nodes = rng.uniform(0, 300, (int(rng.integers(2, 250)), 2))
    dmat = np.hypot(nodes[:, None, 0] - nodes[None, :, 0], nodes[:, None, 1] - nodes[None, :, 1])
    near = cKDTree(nodes).query(nodes, min(6, len(nodes)))[1].tolist()
    assert _nearest_neighbour_tree(nodes, near) == nearest_neighbour(dmat)


def _reversal_gain(nodes: np.ndarray, path: list[int], i: int, j: int) -> float:
    d = lambda a, b: math.dist(nodes[a], nodes[b])  # noqa: E731
    g = d(path[i - 1], path[i]) - d(path[i - 1], path[j])
    if j + 1 < len(path):
        g += d(path[j], path[j + 1]) - d(path[i], path[j + 1])
    return g


@pytest.mark.parametrize("seed", range(4))
def test_neighbour_two_opt_is_a_local_optimum_of_its_neighbourhood(seed: int) -> None:
    """A permutation that starts at the start, no longer than its first tour, and no reversal
    that adds an edge to one of a node's k nearest shortens it (checked by brute force)."""
    rng = np.random.default_rng(seed)
    n = 120
    pts, start = rng.uniform(0, 300, (n, 2)), rng.uniform(0, 300, 2)
    nodes = np.vstack([start[None], pts])
    initial = [int(x) for x in rng.permutation(n)]
    order = _two_opt_neighbours(nodes, initial, k=8)
    assert sorted(order) == list(range(n))
    path = [0] + [v + 1 for v in order]
    assert _length(nodes, path) <= _length(nodes, [0] + [v + 1 for v in initial]) + 1e-9
    dmat = np.hypot(nodes[:, None, 0] - nodes[None, :, 0], nodes[:, None, 1] - nodes[None, :, 1])
    near = [set(np.argsort(row)[:9].tolist()) for row in dmat]
    for i in range(1, n + 1):
        for j in range(i + 1, n + 1):
            a, b, c = path[i - 1], path[i], path[j]
            e = path[j + 1] if j < n else None
            # a shorter new edge at an end of a removed one, to a listed neighbour of that end
            seen = (c in near[a] and dmat[a, c] < dmat[a, b]) or (
                a in near[c] and (e is None or dmat[a, c] < dmat[c, e]))
            if e is not None:
                seen = seen or (e in near[b] and dmat[b, e] < dmat[a, b]) or (
                    b in near[e] and dmat[b, e] < dmat[c, e])
            if seen:
                assert _reversal_gain(nodes, path, i, j) <= 1e-6


@pytest.mark.parametrize("seed", range(8))
def test_matrix_two_opt_makes_the_plain_loops_tour(seed: int) -> None:
    """The numpy 2-opt (gains by rows) returns exactly the plain loop's tour: from random and
    nearest-neighbour tours, on points in general position and on a grid (equal distances)."""
    rng = np.random.default_rng(seed)
    for trial in range(12):
        m = int(rng.integers(2, 90))
        nodes = rng.uniform(0, 300, (m + 1, 2))
        if trial % 3 == 0:
            nodes = np.round(nodes / 50) * 50
        dmat = np.hypot(nodes[:, None, 0] - nodes[None, :, 0], nodes[:, None, 1] - nodes[None, :, 1])
        route = nearest_neighbour(dmat) if trial % 2 else [0, *(int(v) + 1 for v in rng.permutation(m))]
        assert _two_opt_rows(dmat, route) == _two_opt_small(dmat.tolist(), route)


def _two_opt_reference(d: list[list[float]], route: list[int]) -> list[int]:
    """The plain 2-opt loop as first written (every gain read from the matrix)."""
    path = route[:]
    n = len(path) - 1
    improved = True
    while improved:
        improved = False
        for i in range(1, n):
            for j in range(i + 1, n + 1):
                a, b, c = path[i - 1], path[i], path[j]
                if j < n:
                    gain = d[a][b] + d[c][path[j + 1]] - d[a][c] - d[b][path[j + 1]]
                else:
                    gain = d[a][b] - d[a][c]
                if gain > 1e-9:
                    path[i: j + 1] = path[i: j + 1][::-1]
                    improved = True
    return [v - 1 for v in path[1:]]


@pytest.mark.parametrize("seed", range(4))
def test_plain_two_opt_with_edge_list_makes_the_reference_tour(seed: int) -> None:
    """``_two_opt_small`` (edge lengths kept beside the path) makes the reference loop's reversals:
    the same tour, from random and nearest-neighbour tours, general position and a grid."""
    rng = np.random.default_rng(100 + seed)
    for trial in range(30):
        m = int(rng.integers(1, 60))
        nodes = rng.uniform(0, 300, (m + 1, 2))
        if trial % 3 == 0:
            nodes = np.round(nodes / 50) * 50
        dmat = np.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=2)
        route = nearest_neighbour(dmat) if trial % 2 else [0, *(int(v) + 1 for v in rng.permutation(m))]
        assert _two_opt_small(dmat.tolist(), route) == _two_opt_reference(dmat.tolist(), route)


def test_long_tours_are_as_short_as_the_exhaustive_two_opt_within_a_few_percent() -> None:
    rng = np.random.default_rng(7)
    ratios = []
    for _ in range(3):
        pts, start = rng.uniform(0, 300, (150, 2)), rng.uniform(0, 300, 2)
        nodes = np.vstack([start[None], pts])
        fast = two_opt_route(pts, start, long_tours=True)
        dmat = np.hypot(nodes[:, None, 0] - nodes[None, :, 0], nodes[:, None, 1] - nodes[None, :, 1])
        full = _two_opt_small(dmat.tolist(), nearest_neighbour(dmat))
        ratios.append(_length(nodes, [0] + [v + 1 for v in fast])
                      / _length(nodes, [0] + [v + 1 for v in full]))
    assert max(ratios) < 1.05


# ------------------------------------------------------------------ reach regions

def _brute_vertices(discs: list[tuple[float, float, float]]) -> list[tuple[float, float]]:
    out = []
    for a in range(len(discs)):
        for b in range(a + 1, len(discs)):
            (x1, y1, r1), (x2, y2, r2) = discs[a], discs[b]
            d = math.hypot(x2 - x1, y2 - y1)
            if d < 1e-12 or d > r1 + r2 or d < abs(r1 - r2):
                continue
            along = (r1 * r1 - r2 * r2 + d * d) / (2 * d)
            h = math.sqrt(max(r1 * r1 - along * along, 0.0))
            for s in (1, -1):
                q = (x1 + along * (x2 - x1) / d - s * h * (y2 - y1) / d,
                     y1 + along * (y2 - y1) / d + s * h * (x2 - x1) / d)
                if all(math.hypot(q[0] - x, q[1] - y) <= r + 1e-9 for x, y, r in discs):
                    out.append(q)
    return out


@pytest.mark.parametrize("seed", range(5))
def test_disc_vertices_equal_brute_force(seed: int) -> None:
    rng = random.Random(seed)
    for _ in range(200):
        k = rng.randint(1, 9)
        discs = [(rng.uniform(0, 15), rng.uniform(0, 15), rng.uniform(4, 18)) for _ in range(k)]
        got, want = sorted(disc_vertices(discs)), sorted(_brute_vertices(discs))
        assert len(got) == len(want)
        assert all(math.dist(p, q) < 1e-9 for p, q in zip(got, want, strict=True))


def _brute_projection(reg, p: tuple[float, float]) -> tuple[float, float]:
    """Nearest point of I_β: p itself, a disc's nearest point inside I_β, or the nearest vertex."""
    if reg.contains(p):
        return p
    cands = []
    for cx, cy, r in reg.discs:
        n = math.hypot(p[0] - cx, p[1] - cy)
        q = (cx + (p[0] - cx) * r / n, cy + (p[1] - cy) * r / n)
        if reg.contains(q):
            cands.append(q)
    cands += _brute_vertices(reg.discs)
    return min(cands, key=lambda q: math.dist(q, p))


@pytest.mark.parametrize("seed", range(5))
def test_region_projection_equals_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    checked = 0
    for _ in range(300):
        k = int(rng.integers(1, 10))
        g, r, z2 = rng.uniform(0, 15, (k, 2)), rng.uniform(5, 20, k), rng.uniform(0, 4, k)
        reg = make_region(tuple(range(k)), g, r, z2)
        if not reg.feasible:
            continue
        for _ in range(5):
            p = (float(rng.uniform(-40, 55)), float(rng.uniform(-40, 55)))
            assert math.dist(reg.project(p), _brute_projection(reg, p)) < 1e-7
            checked += 1
    assert checked > 500


# ------------------------------------------------------------------ incremental route times

def _deploy(seed: int, n: int = 40, d: float = 12.0) -> DeployProblem:
    rng = random.Random(seed)
    tasks = tuple(Task(f"t{i}", (rng.uniform(0, 150), rng.uniform(0, 150), rng.uniform(0, 3)))
                  for i in range(n))
    return DeployProblem(CARRIER, ROVER, d, (0.0, 0.0, 0.0), 0.3, tasks)


def _same_times(a, b, names: tuple[str, ...]) -> None:
    for name in names:
        assert getattr(a, name) == pytest.approx(getattr(b, name), abs=1e-9), name
    assert a.makespan == pytest.approx(b.makespan, abs=1e-9)


@pytest.mark.parametrize("n", [12, 40])  # routes summed in Python and with numpy (NUMPY_FROM)
@pytest.mark.parametrize("seed", range(4))
def test_deploy_route_moved_and_accept_equal_a_route_timed_afresh(seed: int, n: int) -> None:
    problem = _deploy(seed, n)
    inst = DeployInstance(problem)
    b = DeployBuilder(inst)
    clusters = [[i] for i in range(len(problem.tasks))]
    route = b.route(clusters)
    rng = random.Random(seed)
    names = ("arrive", "heading", "done", "tail", "head")
    for _ in range(30):
        k = rng.randrange(len(route.clusters))
        x, y = route.positions[k]
        q = (x + rng.uniform(-2, 2), y + rng.uniform(-2, 2))
        if rng.random() < 0.2:  # a hop of length zero keeps the heading
            q = route.positions[k - 1] if k else b.start
        moved = route.moved(k, q)
        _same_times(moved, DeployRoute(b, moved.clusters, moved.geos, moved.positions), names)
        i = rng.randrange(len(route.clusters) - 1)
        union = route.clusters[i] + route.clusters[i + 1]
        if inst.fits(union):
            cand = route.replace(i, [union], count=2)
        else:
            cand = route.replace(i, [route.clusters[i + 1], route.clusters[i]], count=2)
        new = route.accept(cand)
        _same_times(new, DeployRoute(b, new.clusters, new.geos, new.positions), names)
        route = new


@pytest.mark.parametrize("n", [12, 40])
@pytest.mark.parametrize("seed", range(4))
def test_deploy_route_with_stops_moved_equals_a_route_timed_afresh(seed: int, n: int) -> None:
    """Route.with_stops (only the hops next to moved stops driven again) gives bit for bit the
    route that Route() times from scratch, zero-length hops (a heading carried on) included."""
    problem = _deploy(seed, n)
    b = DeployBuilder(DeployInstance(problem))
    route = b.route([[i] for i in range(len(problem.tasks))])
    rng = random.Random(seed)
    for _ in range(20):
        new: dict[int, tuple[float, float]] = {}
        for k in rng.sample(range(len(route.clusters)), rng.randint(1, 6)):
            x, y = route.positions[k]
            new[k] = (x + rng.uniform(-2, 2), y + rng.uniform(-2, 2))
            if rng.random() < 0.3:  # onto the previous stop (or the start): the heading is kept
                new[k] = route.positions[k - 1] if k else b.start
        moved = route.with_stops(new)
        fresh = DeployRoute(b, moved.clusters, moved.geos, moved.positions)
        assert moved.positions == [new.get(k, q) for k, q in enumerate(route.positions)]
        for name in ("hop", "heading", "fly", "arrive", "done", "tail", "head", "makespan"):
            assert getattr(moved, name) == getattr(fresh, name), name
        route = moved


@pytest.mark.parametrize("seed", range(4))
def test_a_class_of_stops_scored_at_once_equals_each_stop_scored_alone(seed: int) -> None:
    """StopClass.cost (numpy, every third stop at once) gives stop_cost's makespan (the scalar
    cost, itself checked against a route re-timed from scratch), inf out of reach included; the
    class's search keeps every task in range, and the long routes' polish never slows a route."""
    problem = _deploy(seed, 60)
    b = DeployBuilder(DeployInstance(problem))
    clusters = [[i] for i in range(len(problem.tasks))]
    route = b.route([clusters[i] + clusters[i + 1] if b.inst.fits(clusters[i] + clusters[i + 1])
                     else clusters[i] for i in range(0, len(clusters), 2)])
    rng = np.random.default_rng(seed)
    n = len(route.clusters)
    for c in range(3):
        ks = list(range(c, n - 2, 3))
        sc = StopClass(b, route, ks)
        px = np.array([route.positions[k][0] for k in ks])[:, None] + rng.uniform(-3, 3, (len(ks), 5))
        py = np.array([route.positions[k][1] for k in ks])[:, None] + rng.uniform(-3, 3, (len(ks), 5))
        got = sc.cost(px, py)
        for i, k in enumerate(ks):
            cost = stop_cost(b, route, k)
            for j in range(5):
                want = cost(float(px[i, j]), float(py[i, j]))
                assert got[i, j] == (pytest.approx(want, abs=1e-9) if math.isfinite(want) else want)
        for k in ks[:3]:  # the scalar cost against a route re-timed from scratch
            q = (route.positions[k][0] + 0.5, route.positions[k][1] - 0.25)
            if math.isfinite(stop_cost(b, route, k)(*q)):
                moved = route.moved(k, q)
                assert stop_cost(b, route, k)(*q) == pytest.approx(moved.makespan, abs=1e-9)
        new = search_class(b, route, ks, 0.05)
        for k, q in new.items():
            assert b.inst.reach_from(q, route.clusters[k]) <= b.inst.d + 1e-9
    polished = polish_long(b, route, 0.05)
    assert polished.makespan <= route.makespan
    assert polished.makespan == pytest.approx(
        DeployRoute(b, polished.clusters, polished.geos, polished.positions).makespan, abs=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_the_screen_bounds_every_change_from_below_and_tightly(seed: int) -> None:
    """Route.screen (numpy, many changes at once) against Route.replace (exact, one change): a
    lower bound within 2 MARGIN of the exact makespan, or −inf where it does not score; for
    swaps, divisions in both orders and merges along the whole route."""
    from planners.core.clustering import divide_cluster
    from planners.deploy.screen import MARGIN

    problem = _deploy(seed, 70)
    inst = DeployInstance(problem)
    b = DeployBuilder(inst)
    rng = random.Random(seed)
    clusters: list[list[int]] = []
    for i in range(len(problem.tasks)):  # clusters of one to three tasks, where they fit
        if clusters and len(clusters[-1]) < 3 and rng.random() < 0.5 and inst.fits([*clusters[-1], i]):
            clusters[-1].append(i)
        else:
            clusters.append([i])
    route = b.route(clusters)
    changes = []
    for k in range(len(route.clusters) - 1):
        changes.append((k, [route.clusters[k + 1], route.clusters[k]], 2))
        union = route.clusters[k] + route.clusters[k + 1]
        if inst.fits(union):
            changes.append((k, [union], 2))
        if len(route.clusters[k]) > 1:
            near, far = divide_cluster(route.clusters[k], inst.pts, (0.0, 0.0, 0.0))
            changes += [(k, [near, far], 1), (k, [far, near], 1)]
    bounds = route.screen(changes)
    scored = 0
    for change, bound in zip(changes, bounds, strict=True):
        exact = route.replace(*change)[0]
        assert bound <= exact
        if math.isfinite(bound):
            assert exact - bound <= 2 * MARGIN
            scored += 1
    assert scored > 0.8 * len(changes) - 12  # all but the changes at the start and the end


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(8, 60), st.floats(4.0, 30.0))
def test_the_screen_is_the_exact_re_timing_to_1e9_on_random_routes(seed: int, n: int, d: float) -> None:
    """The screen's numbers (``estimate``: numpy twins of the time model and of max_range_point)
    against Route.replace (the scalar forms) on random routes, carriers and changes: equal to 1e-9
    wherever the screen scores; and max_range_points equal to max_range_point."""
    from planners.core.moves import merge, relocate, swap
    from planners.deploy.cluster import max_range_point, max_range_points
    from planners.deploy.screen import estimate

    rng = random.Random(seed)
    carrier = CarrierSpec(rng.uniform(2.0, 20.0), rng.choice([None, rng.uniform(0.5, 8.0)]),
                          rng.choice([None, rng.uniform(0.3, 4.0)]), unload_time=rng.uniform(0.0, 5.0))
    rover = Motion(rng.uniform(1.0, 5.0), rng.choice([None, rng.uniform(0.5, 4.0)]), rng.uniform(0.0, 2.0))
    size = rng.uniform(2.0, 12.0) * d
    tasks = tuple(Task(f"t{i}", (rng.uniform(0, size), rng.uniform(0, size), rng.uniform(0, d / 3)))
                  for i in range(n))
    problem = DeployProblem(carrier, rover, d, (rng.uniform(-size, 0), rng.uniform(-size, 0), 0.0),
                            rng.uniform(-math.pi, math.pi), tasks)
    inst = DeployInstance(problem)
    b = DeployBuilder(inst)
    order = list(range(n))
    rng.shuffle(order)
    clusters: list[list[int]] = []
    for i in order:  # random clusters of one to four tasks, where they fit
        if clusters and len(clusters[-1]) < 4 and rng.random() < 0.6 and inst.fits([*clusters[-1], i]):
            clusters[-1].append(i)
        else:
            clusters.append([i])
    route = b.route(clusters)
    changes = [ch for move in (swap, relocate, merge) for ch in move(route.clusters, inst.fits_quick, 0)]
    got = estimate(route, changes)
    scored = 0
    for change, value in zip(changes, got, strict=True):
        if math.isfinite(value):
            assert value == pytest.approx(route.replace(*change)[0], rel=0, abs=1e-9)
            scored += 1
    assert scored > 0.5 * len(changes) - 40  # all but the changes at the route's start and end
    geos = route.geos
    for k in range(1, len(geos) - 1):
        prev, nxt = route.positions[k - 1], geos[k + 1].center
        one = max_range_point(prev, geos[k], nxt)
        many = max_range_points(np.array(prev[0]), np.array(prev[1]), np.array(geos[k].center[0]),
                                np.array(geos[k].center[1]), np.array(max(geos[k].slack, 0.0)),
                                np.array(nxt[0]), np.array(nxt[1]))
        assert float(many[0]) == pytest.approx(one[0], rel=0, abs=1e-9)
        assert float(many[1]) == pytest.approx(one[1], rel=0, abs=1e-9)


class _Unscreened(DeployRoute):
    screen = None  # type: ignore[assignment]  # the cluster search scores every change exactly


@pytest.mark.parametrize("seed", range(6))
def test_the_screened_split_loop_keeps_the_same_divisions(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """split_loop with the screen (bounds first, exact scores only where a division might be
    kept) ends on the same route as split_loop scoring every division exactly."""
    from planners.core import search
    from planners.core.clustering import divide_cluster
    from planners.core.search import split_loop

    monkeypatch.setattr(search, "SCREEN_FROM", 0)  # these routes are short: screen them too
    screened = []
    real = DeployRoute.screen
    monkeypatch.setattr(DeployRoute, "screen", lambda r, ch: screened.append(len(ch)) or real(r, ch))

    problem = _deploy(seed, 80, 25.0)
    inst = DeployInstance(problem)
    b = DeployBuilder(inst)
    clusters: list[list[int]] = []
    for c in lee_clusters(problem, improve=False)[0]:  # neighbours merged where one stop serves both
        if clusters and len(clusters[-1]) < 6 and inst.fits(clusters[-1] + c):
            clusters[-1] = clusters[-1] + c
        else:
            clusters.append(c)

    def divide(route: DeployRoute, idx: int) -> tuple[list[int], list[int]]:
        prev = b.start if idx == 0 else route.positions[idx - 1]
        return divide_cluster(route.clusters[idx], inst.pts, (*prev, 0.0))

    plain = b.route(clusters)
    bare = _Unscreened(b, plain.clusters, plain.geos, plain.positions)
    for ties in (True, False):
        fast, slow = split_loop(plain, divide, set(), ties), split_loop(bare, divide, set(), ties)
        assert type(slow) is _Unscreened
        assert fast.clusters == slow.clusters and fast.positions == slow.positions
        assert fast.makespan == slow.makespan
    assert sum(screened) > 20


def _collect(seed: int, n: int = 40) -> CollectProblem:
    rng = random.Random(seed)
    rovers = tuple(CollectRover(f"r{i}", (rng.uniform(0, 150), rng.uniform(0, 150), rng.uniform(0, 3)),
                                rng.uniform(6, 20)) for i in range(n))
    return CollectProblem(CARRIER, ROVER, (0.0, 0.0, 0.0), 0.3, rovers)


def _sequential_collect_times(route) -> tuple[list[float], list[float], list[float]]:
    """Eq. 5.2 step by step: departures, the hops and loads still to come, the latest hold-up."""
    load, n = route.b.load, len(route.hop)
    eta, t = [], 0.0
    for dt, ready in zip(route.hop, route.ready, strict=True):
        t = max(t + dt, ready) + load
        eta.append(t)
    after, late = [0.0] * n, [-math.inf] * n
    for j in range(n - 2, -1, -1):
        after[j] = after[j + 1] + route.hop[j + 1] + load
        late[j] = max(late[j + 1], route.ready[j + 1] + load + after[j + 1])
    return eta, after, late


@pytest.mark.parametrize("n", [12, 40])  # routes summed in Python and with numpy (NUMPY_FROM)
@pytest.mark.parametrize("seed", range(4))
def test_collect_route_prefix_sum_times_equal_the_recursion(seed: int, n: int) -> None:
    problem = _collect(seed, n)
    b = CollectBuilder(CollectInstance(problem))
    rng = random.Random(seed)
    route = b.route([[i] for i in range(len(problem.rovers))])
    for _ in range(20):
        eta, after, late = _sequential_collect_times(route)
        assert route.eta == pytest.approx(eta, abs=1e-9)
        assert route.after == pytest.approx(after, abs=1e-9)
        assert route.late[:-1] == pytest.approx(late[:-1], abs=1e-9) and route.late[-1] == -math.inf
        assert route.makespan == pytest.approx(eta[-1], abs=1e-9)
        k = rng.randrange(len(route.clusters))
        x, y = route.positions[k]
        cand = route.moved(k, route.regions[k].project((x + rng.uniform(-3, 3), y + rng.uniform(-3, 3))))
        fresh = CollectRoute(b, cand.clusters, cand.regions, cand.positions)
        assert cand.makespan == pytest.approx(fresh.makespan, abs=1e-9)
        route = cand


# ------------------------------------------------------------------ phase trace

@pytest.mark.parametrize("kind", ["deploy", "collect"])
@pytest.mark.parametrize("seed", range(3))
def test_the_phase_trace_reports_each_phase_and_changes_nothing(kind: str, seed: int) -> None:
    """``trace`` (bench/phases.py) hears the dissertation's route first and the returned route last,
    with a makespan that no phase of a 30-task quick plan makes worse; the plan is the same as
    without it."""
    from planners.collect.lee import lee_route

    heard: list[tuple[str, float]] = []
    if kind == "deploy":
        problem = _deploy(seed, 30)
        plain = lee_clusters(problem)
        traced = lee_clusters(problem, trace=lambda phase, t: heard.append((phase, t)))
        same, final = plain == traced, traced[2]
    else:
        cproblem = _collect(seed, 30)
        _, route = lee_route(cproblem)
        _, traced_route = lee_route(cproblem, trace=lambda phase, t: heard.append((phase, t)))
        same = (route.clusters, route.positions) == (traced_route.clusters, traced_route.positions)
        final = traced_route.makespan
    assert same
    phases = [p for p, _ in heard]
    assert phases[0] == "dissertation" and phases[-1] == "tiny-problem and budget searches"
    assert {"reorder", "final placement"} <= set(phases)
    times = [t for _, t in heard]
    assert all(b <= a + 1e-9 for a, b in zip(times, times[1:], strict=False)), heard
    assert times[-1] == final and times[-1] < times[0]
