"""Replanning an operation from a live state: rovers in the air keep their work left and are
picked up, the work no rover has is scheduled, no battery goes below its reserve."""

from __future__ import annotations

import dataclasses

import pytest

from planners.core.problem import PlanningError
from planners.operations import InFlight, LiveState, OpTask, air_needed, call_back, plan_operation
from planners.operations.live import call_margin, short_of_battery
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


def _short_rover(seed: int, spare: float) -> tuple:
    """A problem with a rover in the air at its first task (half worked, hovering) with two more
    hovering tasks left, its battery flown so that the first task and the way back to the carrier
    fit with ``spare`` air seconds to spare (negative: they do not)."""
    problem, _spec = instance(seed)
    air, *deck = problem.rovers
    t1, t2, t3, *rest = (dataclasses.replace(t, ground=False) for t in problem.tasks)
    part = dataclasses.replace(t1, duration=t1.duration / 2)
    here = t1.position
    first_only = InFlight(air, here, (part,), 0.0, worked_first=t1.duration / 2)
    flown = problem.air_budget - air_needed(problem, first_only, problem.start) - call_margin(problem) - spare
    f = dataclasses.replace(first_only, tasks=(part, t2, t3), flown=flown)
    state = LiveState(problem.start, problem.heading, dict.fromkeys(deck, 0.0), (f,))
    return dataclasses.replace(problem, tasks=tuple(rest)), state, (t1, t2, t3)


@pytest.mark.parametrize("seed", SEEDS[:6])
def test_a_rover_short_of_battery_in_the_air_is_called_back_keeping_what_fits(seed: int) -> None:
    problem, state, (t1, t2, t3) = _short_rover(seed, spare=1.0)
    f = state.in_flight[0]
    assert short_of_battery(problem, f, state.carrier)  # its whole sortie does not fit any more
    cb = call_back(problem, state)
    assert cb is not None and cb.called_back == {f.rover: [t2.id, t3.id]}  # it keeps the task it is at
    assert [t.id for t in cb.state.in_flight[0].tasks] == [t1.id]
    plan = plan_operation(problem, state)  # called back keeping t1, or keeping none: the earlier end
    dropped = plan.called_back[f.rover]
    assert dropped in ([t2.id, t3.id], [t1.id, t2.id, t3.id])
    own = [s for s in plan.sorties if s.launch_stop == -1]
    kept = [t.id for t in (t1, t2, t3) if t.id not in dropped]
    assert [v.task for v in own[0].visits if v.task] == kept
    worked = [v.task for s in plan.sorties for v in s.visits if v.task]
    assert sorted(worked) == sorted([t1.id, t2.id, t3.id, *(t.id for t in problem.tasks)])  # each once
    others = {v.task: v for s in plan.sorties if s.launch_stop >= 0 for v in s.visits}
    for t in (t1, t2, t3):  # a task dropped is done again in full by another sortie
        if t.id in dropped:
            assert others[t.id].end - others[t.id].arrive == pytest.approx(t.duration)
    assert all(s.battery_left >= problem.reserve - 1e-9 for s in plan.sorties)
    assert plan.to_json()["called_back"] == {f.rover: dropped}


@pytest.mark.parametrize("seed", SEEDS[:6])
def test_a_rover_too_short_even_for_its_task_comes_back_at_once_and_the_task_is_redone_in_full(
        seed: int) -> None:
    problem, state, (t1, t2, t3) = _short_rover(seed, spare=-5.0)
    f = state.in_flight[0]
    cb = call_back(problem, state)
    assert cb is not None and cb.called_back == {f.rover: [t1.id, t2.id, t3.id]}
    assert cb.state.in_flight[0].tasks == ()
    assert [t.duration for t in cb.dropped] == pytest.approx([t1.duration, t2.duration, t3.duration])
    plan = plan_operation(problem, state)
    own = [s for s in plan.sorties if s.launch_stop == -1]
    assert [v.task for v in own[0].visits] == [""]  # no work: it flies back
    others = {v.task: v for s in plan.sorties if s.launch_stop >= 0 for v in s.visits}
    assert others[t1.id].end - others[t1.id].arrive == pytest.approx(t1.duration)  # its half lost
    assert all(s.battery_left >= problem.reserve - 1e-9 for s in plan.sorties)


def test_no_rover_short_of_battery_is_not_called_back() -> None:
    problem, state, _tasks = _short_rover(SEEDS[0], spare=1.0)
    f = state.in_flight[0]
    fine = dataclasses.replace(state, in_flight=(dataclasses.replace(f, flown=0.0, tasks=f.tasks[:1]),))
    assert not short_of_battery(problem, fine.in_flight[0], fine.carrier, call_margin(problem))
    assert call_back(problem, fine) is None
    assert plan_operation(problem, fine).called_back == {}


@pytest.mark.parametrize("seed", SEEDS[:6])
def test_a_rover_into_its_reserve_is_brought_back_by_a_recovery_plan(seed: int) -> None:
    """No plan keeps its reserve (it cannot even come straight back above it): the plan of last
    resort launches nothing, calls it back at once and gives the reserve up; the work waits."""
    problem, state, (t1, t2, t3) = _short_rover(seed, spare=-5.0)
    f = state.in_flight[0]
    back = air_needed(problem, dataclasses.replace(f, tasks=(), flown=0.0), state.carrier)
    into_reserve = dataclasses.replace(
        f, flown=problem.air_budget - back + 0.5 * problem.reserve * problem.endurance)
    state = dataclasses.replace(state, in_flight=(into_reserve,))
    plan = plan_operation(problem, state)
    assert plan.recovery and plan.to_json()["recovery"] is True
    assert plan.called_back == {f.rover: [t1.id, t2.id, t3.id]}
    assert [s.rover for s in plan.sorties] == [f.rover]  # nothing launched, nobody else flies
    assert [v.task for v in plan.sorties[0].visits] == [""] and plan.sorties[0].pickup_stop >= 0
    assert plan.sorties[0].battery_left >= 0.0
    assert not plan_operation(problem, dataclasses.replace(state, in_flight=(f,))).recovery


def test_a_rover_beyond_any_battery_is_not_planned_back() -> None:
    problem, state, _tasks = _short_rover(SEEDS[0], spare=-5.0)
    f = dataclasses.replace(state.in_flight[0], flown=problem.endurance)
    with pytest.raises(PlanningError):
        plan_operation(problem, dataclasses.replace(state, in_flight=(f,)))
