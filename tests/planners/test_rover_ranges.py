"""Rovers with less than the deploy range: planned with the range their battery
has, flown only on tasks they reach, left out when they reach none (planners.core.ranges)."""

from __future__ import annotations

import dataclasses

import pytest

import planners
from planners.core.problem import CarrierSpec, DeployProblem, Motion, PlanningError, Task
from planners.core.ranges import leg_length

BASE = DeployProblem(
    carrier=CarrierSpec(max_speed=10.0, accel=5.0, unload_time=1.0),
    rover=Motion(5.0),
    deploy_range=40.0,
    start=(0.0, 0.0, 0.0),
    heading=0.0,
    tasks=(Task("t1", (60.0, 30.0, 5.0)), Task("t2", (120.0, -20.0, 4.0)), Task("t3", (20.0, 45.0, 6.0))),
    rovers=("r1", "r2", "r3", "r4"),
    takeoff_height=1.0,
)


def _flights(plan: planners.Plan) -> dict[str, float]:
    return {leg.rover: leg_length(leg) for leg in plan.legs() if leg.task is not None}


@pytest.mark.parametrize("name", ["lee", "greedy2opt", "lee-graph"])
def test_each_rover_flies_within_its_battery_range(name: str) -> None:
    # r2 reaches no task (2 m < the lowest task's 3 m above the take-off height); r3 has 12 m
    problem = dataclasses.replace(BASE, rover_ranges=(("r2", 2.0), ("r3", 12.0)))
    plan = planners.DEPLOY_PLANNERS[name](problem)
    flights = _flights(plan)
    assert sorted(leg.task for leg in plan.legs() if leg.task) == ["t1", "t2", "t3"]
    assert "r2" not in flights
    for rid, length in flights.items():
        assert length <= problem.rover_range(rid) + 1e-3, (rid, length)


def test_full_batteries_plan_as_before() -> None:
    full = dataclasses.replace(BASE, rover_ranges=(("r1", 40.0), ("r3", 55.0)))  # above: deploy_range
    assert planners.DEPLOY_PLANNERS["lee"](full).to_json()["stops"] == \
        planners.DEPLOY_PLANNERS["lee"](BASE).to_json()["stops"]


def test_a_short_rover_is_swapped_onto_a_short_flight_without_replanning() -> None:
    three = dataclasses.replace(BASE, rovers=("r1", "r2", "r3"))  # no spare: r1 must fly
    plan = planners.DEPLOY_PLANNERS["lee"](three)
    shortest = min(_flights(plan).values())
    problem = dataclasses.replace(three, rover_ranges=(("r1", shortest + 0.01),))
    again = planners.DEPLOY_PLANNERS["lee"](problem)
    assert again.makespan == pytest.approx(plan.makespan)  # the same route, rovers swapped
    assert _flights(again)["r1"] <= shortest + 0.01 + 1e-6


def test_too_few_rovers_reaching_a_task_is_a_planning_error() -> None:
    problem = dataclasses.replace(BASE, rover_ranges=(("r1", 1.0), ("r2", 2.9)))
    with pytest.raises(PlanningError, match=r"2 rover\(s\) can reach a task for 3 tasks: .*r1 1.0 m, r2 2.9"):
        planners.DEPLOY_PLANNERS["lee"](problem)


def test_when_the_flights_do_not_fit_it_plans_again_with_the_flying_rovers_shortest_range() -> None:
    problem = dataclasses.replace(BASE, rover_ranges=(("r1", 8.0), ("r2", 9.0), ("r3", 30.0), ("r4", 2.0)))
    plan = planners.DEPLOY_PLANNERS["lee"](problem)
    assert "planned with a deploy range of 8.0 m" in " ".join(plan.notes)
    flights = _flights(plan)
    assert set(flights) == {"r1", "r2", "r3"} and max(flights.values()) <= 8.0 + 1e-3
