"""Replanning an operation from a live state: rovers in the air keep their work left and are
picked up, the work no rover has is scheduled, no battery goes below its reserve."""

from __future__ import annotations

import dataclasses

import pytest

from planners.operations import InFlight, LiveState, OpTask, air_needed, plan_operation
from tests.planners.test_operations import instance

# instances with a rover to put in the air and one on the deck
SEEDS = [seed for seed in range(16) if len(instance(seed)[0].rovers) >= 2][:12]


@pytest.mark.parametrize("seed", SEEDS)
def test_the_rest_of_an_operation_is_planned_from_a_live_state(seed: int) -> None:
    problem, _spec = instance(seed)
    air, *deck = problem.rovers
    first, *rest = problem.tasks
    part = dataclasses.replace(first, duration=first.duration / 2)  # half of its work done
    here = (first.position[0], first.position[1], first.position[2])
    flown = 0.2 * problem.endurance
    state = LiveState(problem.start, problem.heading, dict.fromkeys(deck, 0.0),
                      (InFlight(air, here, (part,), flown, first.ground),))
    plan = plan_operation(dataclasses.replace(problem, tasks=tuple(rest)), state)
    worked = [v.task for s in plan.sorties for v in s.visits]
    assert sorted(worked) == sorted(t.id for t in problem.tasks)  # every task once, its own kept
    own = [s for s in plan.sorties if s.launch_stop == -1]
    assert [s.rover for s in own] == [air] and [v.task for v in own[0].visits] == [first.id]
    assert own[0].visits[0].end == pytest.approx(own[0].visits[0].arrive + part.duration)
    assert all(s.pickup_stop >= 0 for s in plan.sorties)  # every rover back on the deck
    assert all(s.battery_left >= problem.reserve - 1e-9 for s in plan.sorties)
    assert own[0].battery_left <= 1.0 - flown / problem.endurance


def test_a_rover_in_the_air_with_no_work_left_is_picked_up() -> None:
    problem, _spec = instance(3)
    state = LiveState(problem.start, problem.heading, {},
                      (InFlight(problem.rovers[0], (10.0, 20.0, 5.0), (), 0.0),))
    plan = plan_operation(dataclasses.replace(problem, tasks=(), rovers=problem.rovers[:1]), state)
    assert len(plan.sorties) == 1 and plan.sorties[0].pickup_stop == 0
    assert isinstance(problem.tasks[0], OpTask)


def test_the_air_a_rover_still_needs_counts_hovering_work_and_the_way_back() -> None:
    problem, _spec = instance(3)
    rover, here, stop = problem.rovers[0], (40.0, 60.0, 5.0), (0.0, 0.0, 0.0)
    back = air_needed(problem, InFlight(rover, here, (), 0.0), stop)
    assert back > 0.0
    hover = OpTask("a", here, 100.0, ground=False)
    assert air_needed(problem, InFlight(rover, here, (hover,), 0.0), stop) == pytest.approx(back + 100.0)
    landed = OpTask("a", (here[0], here[1], 0.0), 100.0, ground=True)  # landed there: work costs nothing
    on_ground = air_needed(problem, InFlight(rover, landed.position, (landed,), 0.0, True), stop)
    idle = air_needed(problem, InFlight(rover, landed.position, (), 0.0, True), stop)
    assert on_ground == pytest.approx(idle)
    far = OpTask("b", (here[0] + 100.0, here[1], 5.0), 0.0)
    assert air_needed(problem, InFlight(rover, here, (far,), 0.0), stop) > back
