"""The one search driver (planners.core.driver): deployment and collection run the same sequence,
gated by the same sizes, and a budget only ever keeps improvements."""

from __future__ import annotations

import collections
from collections.abc import Callable
from typing import Any

import pytest

from bench.optimality import collect_instance, deploy_instance
from planners.collect.instance import CollectInstance
from planners.collect.lee import CollectSpace, _initial_clusters
from planners.collect.path import PathBuilder as CollectBuilder
from planners.core import driver
from planners.deploy.cluster import DeployInstance
from planners.deploy.lee import DeploySpace, _divided
from planners.deploy.path import PathBuilder as DeployBuilder


class Spy:
    """A search space that counts what the driver asks of the real one."""

    def __init__(self, space: Any) -> None:
        self.space, self.calls = space, collections.Counter[str]()
        self.size, self.cheap, self.fits, self.rebuild = space.size, space.cheap, space.fits, space.rebuild

    def finish(self, route: Any, small: bool, improve: bool) -> Any:
        self.calls["finish"] += 1
        return self.space.finish(route, small, improve)

    def smooth(self, route: Any) -> Any:
        self.calls["smooth"] += 1
        return self.space.smooth(route)

    def flown(self, route: Any) -> float:
        self.calls["flown"] += 1
        return float(self.space.flown(route))

    def ranking(self) -> Callable[[list[list[int]]], Any] | None:
        return self.space.ranking()


def _deploy(n: int, seed: int) -> tuple[Spy, Any]:
    problem = deploy_instance(n, seed)
    builder = DeployBuilder(DeployInstance(problem))
    return Spy(DeploySpace(problem, builder)), _divided(builder, True, lambda *a: None)


def _collect(n: int, seed: int) -> tuple[Spy, Any]:
    problem = collect_instance(n, seed)
    builder = CollectBuilder(CollectInstance(problem))
    return Spy(CollectSpace(problem, builder)), builder.route(_initial_clusters(builder))


@pytest.mark.parametrize("make", [_deploy, _collect], ids=["deploy", "collect"])
def test_both_problems_run_the_same_sequence(make: Callable[[int, int], tuple[Spy, Any]]) -> None:
    heard: dict[str, list[str]] = {}
    for n in (4, 12):
        space, route = make(n, 1)
        phases: list[str] = heard.setdefault(str(n), [])
        best = driver.search(space, route, trace=lambda phase, t, into=phases: into.append(phase))
        assert best.makespan <= space.finish(route, n <= driver.FINE_UPTO, True).makespan + 1e-9
        # short routes end on the plan as it flies; longer ones never smooth or build plans
        assert (space.calls["flown"] > 0) == (n <= driver.SMOOTH_UPTO)
        assert (space.calls["smooth"] > 0) == (n <= driver.SMOOTH_UPTO)
    assert heard["4"][1:] == heard["12"][1:] == ["final placement", "tiny-problem and budget searches"]
    assert heard["4"][0] == heard["12"][0] and " and merge" in heard["4"][0]


@pytest.mark.parametrize("make", [_deploy, _collect], ids=["deploy", "collect"])
def test_a_budget_keeps_only_improvements(make: Callable[[int, int], tuple[Spy, Any]]) -> None:
    space, route = make(10, 3)
    quick = driver.search(space, route)
    space, route = make(10, 3)
    spent = driver.search(space, route, budget_ms=150.0, seed=1)
    assert spent.makespan <= quick.makespan + 1e-9
    assert space.calls["finish"] > 0


def test_without_the_tiny_searches_fewer_routes_are_placed() -> None:
    space, route = _deploy(5, 2)
    driver.search(space, route)
    every = space.calls["finish"]
    space, route = _deploy(5, 2)
    driver.search(space, route, tiny_search=False)
    assert space.calls["finish"] < every and space.calls["smooth"] == 0
