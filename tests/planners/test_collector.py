"""Planners run with fewer garbage-collector passes (``planners.core.collector``), and the
caller's thresholds come back afterwards, whatever the nesting, threads or errors."""

from __future__ import annotations

import gc
import threading
from collections.abc import Iterator
from typing import Any

import pytest

from planners import DEPLOY_PLANNERS, LazyPlanner
from planners.core.collector import PLANNING_THRESHOLD, fewer_collections
from planners.core.problem import CarrierSpec, DeployProblem, Motion, Task

SEEN: list[tuple[int, int, int]] = []


def record(problem: Any) -> Any:
    """A stand-in planner (imported by LazyPlanner by name): the thresholds it runs with."""
    SEEN.append(gc.get_threshold())
    if problem == "fail":
        raise ValueError("no plan")
    return problem


@pytest.fixture
def thresholds() -> Iterator[tuple[int, int, int]]:
    """The test's own thresholds (not the defaults, so that restoring them is seen), put back after."""
    before = gc.get_threshold()
    gc.set_threshold(900, 11, 12)
    SEEN.clear()
    yield (900, 11, 12)
    gc.set_threshold(*before)


def test_a_registry_planner_runs_with_fewer_collections_and_restores_the_thresholds(
        thresholds: tuple[int, int, int]) -> None:
    planner = LazyPlanner("tests.planners.test_collector", "record")
    assert planner("plan") == "plan"
    assert SEEN == [(PLANNING_THRESHOLD, 11, 12)]
    assert gc.get_threshold() == thresholds
    with pytest.raises(ValueError):
        planner("fail")
    assert SEEN[-1] == (PLANNING_THRESHOLD, 11, 12)
    assert gc.get_threshold() == thresholds


def test_a_real_plan_leaves_the_thresholds_as_they_were(thresholds: tuple[int, int, int]) -> None:
    problem = DeployProblem(CarrierSpec(10.0, 2.0, 1.0, unload_time=2.0), Motion(2.0), 15.0, (0.0, 0.0, 0.0),
                            0.0, tuple(Task(f"t{i}", (10.0 * i, 5.0 * (i % 3), 0.0)) for i in range(12)))
    assert DEPLOY_PLANNERS["lee"](problem).makespan > 0
    assert gc.get_threshold() == thresholds


def test_nested_and_concurrent_planners_restore_the_thresholds_when_the_last_returns(
        thresholds: tuple[int, int, int]) -> None:
    inside, release = threading.Event(), threading.Event()

    def other() -> None:
        with fewer_collections():
            inside.set()
            release.wait(10.0)

    with fewer_collections():
        with fewer_collections():
            assert gc.get_threshold()[0] == PLANNING_THRESHOLD
        assert gc.get_threshold()[0] == PLANNING_THRESHOLD  # the outer call still runs
        worker = threading.Thread(target=other)
        worker.start()
        assert inside.wait(10.0)
    assert gc.get_threshold()[0] == PLANNING_THRESHOLD  # this thread left, the other still plans
    release.set()
    worker.join(10.0)
    assert gc.get_threshold() == thresholds


def test_a_caller_with_a_higher_threshold_keeps_it(thresholds: tuple[int, int, int]) -> None:
    gc.set_threshold(10 * PLANNING_THRESHOLD, 11, 12)
    with fewer_collections():
        assert gc.get_threshold() == (10 * PLANNING_THRESHOLD, 11, 12)
    assert gc.get_threshold() == (10 * PLANNING_THRESHOLD, 11, 12)
