"""Long operations: the planner's and the waves baseline's schedules checked by the
independent checker (tests/operation_checker.py) on random instances, the lower bound below both,
and the checker catching broken schedules."""

from __future__ import annotations

import copy
import random
from typing import Any

import pytest

from planners.core.problem import CarrierSpec, Motion, PlanningError
from planners.operations import OperationProblem, OpTask, operation_lower_bound, plan_operation, plan_waves
from tests.operation_checker import OpSpec, check_operation


def instance(seed: int) -> tuple[OperationProblem, OpSpec]:
    """A random operation: 2–4 times more tasks than rovers, 30–300 s of work each, hovering,
    landed or mixed, with and without acceleration, turn rate and swap time."""
    rng = random.Random(seed)
    n_rovers = rng.randint(1, 6)
    side = rng.choice([80.0, 300.0, 700.0])
    mode = rng.choice(["hover", "ground", "mixed"])
    tasks = tuple(OpTask(f"t{i + 1}", (rng.uniform(-side, side), rng.uniform(0, side), rng.uniform(0, 12)),
                         rng.uniform(30, 300), mode == "ground" or (mode == "mixed" and rng.random() < 0.5))
                  for i in range(n_rovers * rng.randint(2, 4)))
    accel = rng.choice([None, 2.0])
    turn = rng.choice([None, 1.0])
    unload, load = rng.uniform(0, 5), rng.uniform(0, 5)
    tau, lam = rng.choice([0.0, 1.1]), rng.choice([0.0, 3.1])
    v_r, a_r = rng.uniform(3, 8), rng.choice([None, 3.0])
    swap = rng.choice([0.0, 20.0, 60.0])
    endurance = rng.uniform(500, 900)
    deploy = rng.uniform(60, 200)
    start = (rng.uniform(-50, 50), rng.uniform(-50, 0), 0.0)
    heading = rng.uniform(-3, 3)
    carrier = CarrierSpec(12.0, accel, turn, unload, load, tau, lam)
    problem = OperationProblem(carrier, Motion(v_r, a_r), start, heading,
                               tasks, tuple(f"r{i + 1}" for i in range(n_rovers)), deploy_range=deploy,
                               endurance=endurance, reserve=0.1, swap_time=swap, takeoff_height=1.0,
                               approach_height=3.0)
    spec = OpSpec(12.0, accel, turn, unload, load, tau, lam, v_r, a_r, deploy, endurance, 0.1, swap, 1.0, 3.0,
                  {t.id: (t.position, t.duration, t.ground) for t in tasks}, problem.rovers)
    return problem, spec


SEEDS = range(40)


@pytest.mark.parametrize("seed", SEEDS)
def test_planned_operations_pass_the_independent_checker(seed: int) -> None:
    problem, spec = instance(seed)
    plan = plan_operation(problem).to_json()
    makespan = check_operation(plan, spec)
    assert makespan >= operation_lower_bound(problem) - 1e-6


@pytest.mark.parametrize("seed", SEEDS)
def test_waves_pass_the_independent_checker(seed: int) -> None:
    problem, spec = instance(seed)
    plan = plan_waves(problem).to_json()
    makespan = check_operation(plan, spec)
    assert makespan >= operation_lower_bound(problem) - 1e-6


def test_rovers_chain_tasks_and_are_relaunched_after_a_swap() -> None:
    """Short tasks close together: one sortie works several; more tasks than rovers: a rover flies
    again, after a swap on the deck."""
    tasks = tuple(OpTask(f"t{i}", (10.0 * i, 5.0, 3.0), 30.0) for i in range(6))
    carrier = CarrierSpec(10.0, None, None, 2.0, 2.0, 1.0, 2.0)
    problem = OperationProblem(carrier, Motion(4.0), (0.0, 0.0, 0.0), 0.0, tasks, ("r1",),
                               deploy_range=100.0, endurance=150.0, swap_time=15.0)
    plan = plan_operation(problem)
    assert max(len(s.visits) for s in plan.sorties) >= 2
    assert len(plan.sorties) >= 2 and plan.swaps
    assert all(w.end - w.start == pytest.approx(15.0) for w in plan.swaps)


def test_a_task_longer_than_a_battery_is_refused() -> None:
    tasks = (OpTask("t1", (10.0, 0.0, 3.0), 200.0),)
    problem = OperationProblem(CarrierSpec(10.0), Motion(4.0), (0.0, 0.0, 0.0), 0.0, tasks, ("r1",),
                               deploy_range=100.0, endurance=150.0)
    with pytest.raises(PlanningError):
        plan_operation(problem)
    landed = OperationProblem(CarrierSpec(10.0), Motion(4.0), (0.0, 0.0, 0.0), 0.0,
                              (OpTask("t1", (10.0, 0.0, 0.0), 200.0, ground=True),), ("r1",),
                              deploy_range=100.0, endurance=150.0)
    assert plan_operation(landed).sorties[0].air_time < 150.0  # landed, the work costs no battery


def _breakages(plan: dict[str, Any]) -> list[dict[str, Any]]:
    """Copies of ``plan`` each broken in one way the checker must see."""
    out = []
    s = copy.deepcopy(plan)
    s["sorties"][0]["visits"][0]["end"] -= 5.0  # worked too short
    out.append(s)
    s = copy.deepcopy(plan)
    s["stops"][0]["arrive"] -= 1.0  # the carrier there before it could drive there
    out.append(s)
    s = copy.deepcopy(plan)
    s["sorties"][-1]["pickup_stop"] = -1  # a rover never picked up
    out.append(s)
    s = copy.deepcopy(plan)
    # a task never worked, or one twice
    s["sorties"][0]["visits"] = s["sorties"][0]["visits"][1:] or s["sorties"][1]["visits"]
    out.append(s)
    s = copy.deepcopy(plan)
    s["makespan"] -= 1.0
    out.append(s)
    return out


def test_the_checker_catches_broken_schedules() -> None:
    problem, spec = instance(3)
    plan = plan_operation(problem).to_json()
    check_operation(plan, spec)
    for broken in _breakages(plan):
        with pytest.raises((AssertionError, IndexError, KeyError)):
            check_operation(broken, spec)


def test_the_checker_catches_a_rover_below_its_reserve_and_a_missing_swap() -> None:
    problem, spec = instance(5)
    plan = plan_operation(problem).to_json()
    used = max(s["air_time"] for s in plan["sorties"]) / spec.endurance  # the most a sortie takes
    tight = OpSpec(**{**spec.__dict__, "reserve": 1.0 - used + 0.01})
    with pytest.raises(AssertionError, match="reserve|battery"):
        check_operation(plan, tight)
    again = [s for s in plan["sorties"] if any(o["rover"] == s["rover"] and o["takeoff"] < s["takeoff"]
                                               for o in plan["sorties"])]
    assert again, "the instance relaunches a rover"
    no_swaps = copy.deepcopy(plan)
    no_swaps["rovers"] = {r: [e for e in rows if e["kind"] != "swap"] for r, rows in plan["rovers"].items()}
    with pytest.raises(AssertionError, match="swap"):
        check_operation(no_swaps, spec)
