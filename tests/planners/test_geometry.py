"""Minimum enclosing circle/sphere (ch. 3.4) and the cluster divider (Algorithm 3.1)."""

import math
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

from planners.core import geometry
from planners.core.clustering import divide_cluster
from planners.core.geometry import EnclosingCircles, enclosing_ball, minimize_1d

coord = st.floats(-100, 100, allow_nan=False, allow_infinity=False)


def _points(dim):
    return st.lists(st.tuples(*[coord] * dim), min_size=1, max_size=25)


def _reference_radius(pts):
    # The optimum of eq. 3.1 by a generic solver, from the centroid.
    arr = np.array(pts)
    f = lambda c: np.max(np.linalg.norm(arr - c, axis=1))  # noqa: E731
    best = minimize(f, arr.mean(axis=0), method="Nelder-Mead",
                    options={"xatol": 1e-10, "fatol": 1e-10, "maxiter": 20000})
    return best.fun


@settings(max_examples=60, deadline=None)
@given(st.one_of(_points(2), _points(3)))
def test_ball_encloses_every_point_and_is_minimal(pts):
    ball = enclosing_ball(pts)
    for p in pts:
        assert math.dist(ball.center, p) <= ball.radius + 1e-6
    assert ball.radius <= _reference_radius(pts) + 1e-6
    # Minimal: some point lies on the boundary (or all points coincide).
    assert max(math.dist(ball.center, p) for p in pts) >= ball.radius - 1e-6


@settings(max_examples=40, deadline=None)
@given(coord, coord, coord, coord, st.integers(3, 12))
def test_collinear_points(x0, y0, dx, dy, n):
    pts = [(x0 + k * dx / n, y0 + k * dy / n) for k in range(n + 1)]
    ball = enclosing_ball(pts)
    half = math.dist(pts[0], pts[-1]) / 2
    assert abs(ball.radius - half) <= 1e-6 * max(1.0, half)


def test_special_cases():
    assert enclosing_ball([(3.0, 4.0)]).radius == 0.0
    b = enclosing_ball([(0.0, 0.0), (2.0, 0.0)])
    assert b.center == (1.0, 0.0) and b.radius == 1.0
    b = enclosing_ball([(1.0, 1.0, 1.0)] * 5)
    assert b.radius == 0.0
    b = enclosing_ball([(0, 0), (4, 0), (0, 4), (0, 0), (4, 0)])  # duplicates, right triangle
    assert b.radius == math.sqrt(8)
    b = enclosing_ball([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, 0, 1), (0, 0, -1)])
    assert abs(b.radius - 1.0) < 1e-9


def test_weighted_ball_is_the_best_ground_point_for_tasks_at_height():
    # Two tasks 20 m apart at 10 m height: the ground midpoint reaches both at sqrt(200).
    b = enclosing_ball([(0.0, 0.0), (20.0, 0.0)], [100.0, 100.0])
    assert b.center == (10.0, 0.0)
    assert abs(b.radius - math.sqrt(200)) < 1e-12


def test_minimize_1d():
    x, v = minimize_1d(lambda s: (s - 0.3) ** 2 + 1, 0.0, 1.0)
    assert abs(x - 0.3) < 1e-4 and abs(v - 1) < 1e-8


def test_divider_splits_around_the_farthest_pair():
    pts = [(0, 0, 0), (1, 0, 0), (10, 0, 0), (11, 0, 0), (5.4, 0, 0)]
    near, far = divide_cluster(range(5), pts, (-5, 0, 0))
    assert sorted(near) == [0, 1, 4] and sorted(far) == [2, 3]
    near, far = divide_cluster(range(5), pts, (20, 0, 0))  # GET_ORDER: nearer part first
    assert sorted(near) == [2, 3]


def test_divider_tie_rule_prefers_the_task_nearest_the_carrier():
    # From the first task p0 the farthest is A; B1 and B2 are equally far from A. The carrier is
    # nearer B2, so the pair (A, B2) is used although B1 comes first in the list.
    p0, a, b1, b2 = (6, 6, 0), (0, 0, 0), (10, 0, 0), (0, 10, 0)
    near, far = divide_cluster([0, 1, 2, 3], [p0, a, b1, b2], (0, 30, 0))
    assert sorted(near) == [0, 3] and sorted(far) == [1, 2]
    # With the carrier nearer B1 the other pair wins.
    near, far = divide_cluster([0, 1, 2, 3], [p0, a, b1, b2], (30, 0, 0))
    assert sorted(near) == [0, 2] and sorted(far) == [1, 3]


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(coord, coord, st.floats(0, 10)), min_size=2, max_size=30))
def test_divider_partitions(pts):
    near, far = divide_cluster(range(len(pts)), pts, (0, 0, 0))
    assert near and far
    assert sorted(near + far) == list(range(len(pts)))


def _walk(rng, pts, weights, steps, cache, size=(1, 12)):
    """Random add / remove / exchange steps from a random cluster: yields (key, previous key)."""
    n = len(pts)
    cur = tuple(sorted(rng.sample(range(n), min(5, n))))
    for _ in range(steps):
        s = set(cur)
        op = rng.random()
        if op < 0.35:
            s.discard(rng.choice(cur))
        if op > 0.3:
            s.add(rng.randrange(n))
        if size[0] <= len(s) <= size[1]:
            prev, cur = cur, tuple(sorted(s))
            yield cur, prev


@pytest.mark.parametrize("weighted", [False, True])
def test_incremental_circles_are_welzls_bit_for_bit(weighted, monkeypatch):
    # Generic points: a circle derived from a neighbouring cluster's is the very ball Welzl's
    # algorithm computes on the new cluster (the planners' searches are chaotic: any other last
    # bit would change the plans), and most circles are derived (Welzl runs far fewer times).
    calls = []
    welzl = geometry._welzl_2d
    monkeypatch.setattr(geometry, "_welzl_2d", lambda *a: calls.append(1) or welzl(*a))
    rng = random.Random(7 + weighted)
    pts = [(rng.uniform(0, 200), rng.uniform(0, 200)) for _ in range(40)]
    w = [rng.uniform(0, 400) if weighted else 0.0 for _ in pts]
    cache = EnclosingCircles(pts)
    new = fresh = 0
    for key, prev in _walk(rng, pts, w, 4000, cache):
        new += key not in cache._known
        ws = [w[i] for i in key]
        before = len(calls)
        got = cache.get(key, ws, (prev,))
        fresh += len(calls) - before
        ref = enclosing_ball([pts[i] for i in key], ws)
        assert (got[:2], got[2]) == (ref.center, ref.radius)
    assert new > 1000 and fresh < 0.6 * new


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 4), st.integers(0, 4)), min_size=2, max_size=12),
       st.lists(st.sampled_from([0.0, 1.0, 4.0]), min_size=12, max_size=12), st.integers(0, 10**6),
       st.booleans())
def test_incremental_circles_on_degenerate_points(grid, wlist, seed, weighted):
    # A 5 x 5 grid: duplicates, collinear and cocircular points. Welzl's algorithm may end on
    # another support there, so the derived ball must be the same ball up to rounding.
    pts = [(float(x), float(y)) for x, y in grid]
    w = wlist[:len(pts)] if weighted else [0.0] * len(pts)
    rng = random.Random(seed)
    cache = EnclosingCircles(pts)
    for key, prev in _walk(rng, pts, w, 30, cache, size=(1, len(pts))):
        ws = [w[i] for i in key]
        got = cache.get(key, ws, (prev, key[1:]))
        ref = enclosing_ball([pts[i] for i in key], ws)
        assert math.dist(got[:2], ref.center) <= 1e-6 and abs(got[2] - ref.radius) <= 1e-6
        for i in key:
            assert math.dist(got[:2], pts[i]) ** 2 + w[i] <= (got[2] + 1e-6) ** 2


def test_incremental_circles_special_cases():
    pts = [(0.0, 0.0), (4.0, 0.0), (0.0, 4.0), (4.0, 4.0), (2.0, 2.0), (2.0, 2.0), (8.0, 0.0)]
    cache = EnclosingCircles(pts)
    square = cache.get((0, 1, 2, 3))  # four cocircular points
    assert math.dist(square[:2], (2.0, 2.0)) < 1e-12 and abs(square[2] - math.sqrt(8)) < 1e-12
    inner = cache.get((0, 1, 2, 3, 4), near=[(0, 1, 2, 3)])  # an added point inside: unchanged
    assert inner == square
    assert cache.get((4, 5), near=[(4,)]) == (2.0, 2.0, 0.0)  # duplicates
    line = cache.get((0, 1, 6), near=[(0, 1)])  # collinear, the added point outside
    assert line == (4.0, 0.0, 4.0)
    assert cache.get((0, 6), near=[(0, 1, 6)]) == line  # removed a point off the support
    assert cache.get((1, 6), near=[(0, 1, 6)])[2] == 2.0  # removed a support point
    heavy = cache.get((0, 1), [100.0, 0.0], near=[(0,)])  # power weights: a heavy point holds it alone
    assert heavy == (0.0, 0.0, 10.0)
