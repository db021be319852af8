"""The collection route's screen (``planners.collect.screen``): lower bounds of many changes at once
that let the cluster search skip exact scores, never a change it would keep."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planners.collect import lee
from planners.collect.instance import CollectInstance
from planners.collect.path import PathBuilder, Route
from planners.core.clustering import divide_cluster
from planners.core.moves import merge, relocate, reverse, shift, split_off, swap
from planners.core.problem import CarrierSpec, CollectProblem, CollectRover, Motion


def _problem(rng: random.Random, n: int, size: float) -> CollectProblem:
    carrier = CarrierSpec(rng.uniform(2.0, 20.0), rng.choice([None, rng.uniform(0.5, 8.0)]),
                          rng.choice([None, rng.uniform(0.3, 4.0)]), load_time=rng.uniform(0.0, 5.0),
                          land_time=rng.choice([0.0, rng.uniform(0.0, 2.0)]))
    rover = Motion(rng.uniform(1.0, 5.0), rng.choice([None, rng.uniform(0.5, 4.0)]), rng.uniform(0.0, 2.0))
    rovers = tuple(CollectRover(f"r{i}", (rng.uniform(0, size), rng.uniform(0, size), rng.uniform(0, 3)),
                                rng.uniform(4.0, 25.0)) for i in range(n))
    return CollectProblem(carrier, rover, (rng.uniform(-size, 0), rng.uniform(-size, 0), 0.0),
                          rng.uniform(-math.pi, math.pi), rovers)


def _changes(route: Route, inst: CollectInstance) -> list[tuple[int, list[list[int]], int]]:
    """Every move of the search along the route, and Algorithm 5.2's divisions in both orders."""
    moves = (swap, relocate, merge, split_off, shift, reverse)
    out = [ch for move in moves for ch in move(route.clusters, inst.fits, 0)]
    for k, c in enumerate(route.clusters):
        if len(c) > 1:
            near, far = divide_cluster(c, inst.pts2, route.b.start if k == 0 else route.positions[k - 1])
            out += [(k, [near, far], 1), (k, [far, near], 1)]
    return out


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(6, 50), st.floats(20.0, 200.0), st.booleans())
def test_the_screen_bounds_every_change_from_below(seed: int, n: int, size: float, before: bool) -> None:
    """On random carriers, rovers, clusters and changes (every move, divisions), with the stop before
    a change placed afresh or kept: the screen is at most the exact makespan ``replace`` gives, and
    a change with a kept stop after it gets a finite bound."""
    rng = random.Random(seed)
    problem = _problem(rng, n, size)
    inst = CollectInstance(problem)
    b = PathBuilder(inst)
    b.replace_before = before
    route = b.route(lee._initial_clusters(b))
    changes = _changes(route, inst)
    bounds = route.screen(changes)
    for change, bound in zip(changes, bounds, strict=True):
        assert bound <= route.replace(*change)[0]
        i, _, count = change
        assert math.isfinite(bound) == (i + count < len(route.clusters))


def _dense(n: int, seed: int) -> CollectProblem:
    """bench/scaling.py's collection instances (ranges 5–20 m in a 200 m square)."""
    rng = random.Random(seed)
    carrier = CarrierSpec(15.0, 5.0, 3.0, load_time=3.0)
    rovers = tuple(CollectRover(f"r{i}", (rng.uniform(0, 200), rng.uniform(0, 200), 0.0), rng.uniform(5, 20))
                   for i in range(n))
    return CollectProblem(carrier, Motion(3.0), (rng.uniform(0, 200), rng.uniform(0, 200), 0.0), 0.5, rovers)


def test_the_screen_rules_out_most_divisions_of_a_long_route() -> None:
    """Where the carrier's driving sets the makespan (600 rovers in a 200 m square), a division's
    extra stop is not won back and its bound shows it: most divisions are never scored exactly."""
    inst = CollectInstance(_dense(600, 1))
    b = PathBuilder(inst)
    b.replace_before = False  # as lee_route on routes this long (QD_KEEP_BEFORE_FROM)
    route = b.route(lee._initial_clusters(b))
    divisions = [ch for ch in _changes(route, inst) if len(ch[1]) == 2 and ch[2] == 1]
    bounds = route.screen(divisions)
    exact = np.array([route.replace(*ch)[0] for ch in divisions])
    assert np.all(bounds <= exact)
    assert np.sum(bounds > route.makespan) > 0.6 * len(divisions)


class _Unscreened(Route):
    screen = None  # type: ignore[assignment]  # the cluster search scores every change exactly


@pytest.mark.parametrize("seed", range(3))
def test_the_screened_split_loop_keeps_the_same_divisions(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """split_loop with the screen ends on the same route as split_loop scoring every division
    exactly, on long routes (the screen's) and short ones screened too."""
    from planners.core import search

    monkeypatch.setattr(search, "SCREEN_FROM", 0)
    screened: list[int] = []
    real = Route.screen
    monkeypatch.setattr(Route, "screen", lambda r, ch: screened.append(len(ch)) or real(r, ch))
    for n, before in ((60, True), (400, False)):
        inst = CollectInstance(_dense(n, seed))
        b = PathBuilder(inst)
        b.replace_before = before

        def divide(route: Route, idx: int, b: PathBuilder = b) -> tuple[list[int], list[int]]:
            prev = b.start if idx == 0 else route.positions[idx - 1]
            return divide_cluster(route.clusters[idx], b.inst.pts2, prev)

        plain = b.route(lee._initial_clusters(b))
        bare = _Unscreened(b, plain.clusters, plain.regions, plain.positions)
        for ties in (True, False):
            fast = search.split_loop(plain, divide, set(), ties)
            slow = search.split_loop(bare, divide, set(), ties)
            assert type(slow) is _Unscreened
            assert fast.clusters == slow.clusters and fast.positions == slow.positions
            assert fast.makespan == slow.makespan
    assert sum(screened) > 20
