"""Deployment planners on random 2D and 3D instances, checked independently (tests/plan_checker.py)."""

import math
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planners import DEPLOY_PLANNERS, PlanningError, deploy_lower_bound
from planners.core.problem import CarrierSpec, DeployProblem, Motion, Task
from planners.deploy.two_task import apollonius_circle, apollonius_point, plan_two_tasks
from tests.plan_checker import check_plan


def random_problem(seed: int, n: int, three_d: bool, size: float = 150.0) -> DeployProblem:
    rng = random.Random(seed)
    d = rng.uniform(6.0, 40.0)
    accel = rng.choice([None, rng.uniform(1.0, 10.0)])
    carrier = CarrierSpec(max_speed=rng.uniform(5.0, 20.0), accel=accel,
                          turn_rate=rng.choice([None, rng.uniform(0.5, 4.0)]),
                          unload_time=rng.uniform(0.0, 5.0), load_time=rng.uniform(0.0, 5.0))
    rover = Motion(rng.uniform(0.5, 4.0), rng.choice([None, rng.uniform(0.5, 3.0)]))
    tasks = tuple(Task(f"t{i}", (rng.uniform(0, size), rng.uniform(0, size),
                                 rng.uniform(0, min(d, 12.0)) if three_d else 0.0)) for i in range(n))
    start = (rng.uniform(0, size), rng.uniform(0, size), 0.0)
    spares = rng.randint(0, 3)
    rovers = tuple(f"r{i + 1}" for i in range(n + spares))
    return DeployProblem(carrier, rover, d, start, rng.uniform(-math.pi, math.pi), tasks, rovers)


def as_dicts(p: DeployProblem):
    c = p.carrier
    return ({"max_speed": c.max_speed, "accel": c.accel, "turn_rate": c.turn_rate,
             "unload_time": c.unload_time, "load_time": c.load_time, "takeoff_time": c.takeoff_time,
             "land_time": c.land_time},
            {"max_speed": p.rover.max_speed, "accel": p.rover.accel, "fixed_time": p.rover.fixed_time})


def check(problem: DeployProblem, planner: str) -> dict:
    try:
        plan = DEPLOY_PLANNERS[planner](problem).to_json()
    except PlanningError:
        assert planner in ("direct", "two-task")
        return {}
    carrier, rover = as_dicts(problem)
    recomputed = check_plan(plan, carrier, rover, problem.deploy_range)
    assert plan["kind"] == "deploy" and plan["planner"] == planner
    served = [r["task"] for s in plan["stops"] for r in s["rovers"]]
    assert sorted(served) == sorted(t.id for t in problem.tasks), "every task exactly once"
    used = [r["rover"] for s in plan["stops"] for r in s["rovers"]]
    assert len(set(used)) == len(used), "distinct rovers"
    assert set(used) <= set(problem.rover_ids()), "rovers of the fleet"
    by_id = {t.id: t.position for t in problem.tasks}
    for s in plan["stops"]:
        assert abs(s["position"][2]) < 1e-9, "the carrier stays on the ground"
        for r in s["rovers"]:
            assert math.dist(r["target"], by_id[r["task"]]) < 1e-5
    assert deploy_lower_bound(problem) <= recomputed + 1e-6
    return plan


@pytest.mark.parametrize("planner", ["lee", "greedy2opt", "direct"])
@pytest.mark.parametrize("three_d", [False, True])
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(1, 30))
def test_planner_properties(planner, three_d, seed, n):
    check(random_problem(seed, n, three_d), planner)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10**6))
def test_direct_when_every_task_is_in_range(seed):
    p = random_problem(seed, 6, True, size=10.0)
    p = DeployProblem(p.carrier, p.rover, 40.0, p.start, p.heading, p.tasks, p.rovers)
    plan = check(p, "direct")
    assert len(plan["stops"]) == 1 and plan["stops"][0]["arrive"] == 0.0


def test_direct_refuses_out_of_range_tasks_by_name():
    p = random_problem(1, 3, False)
    far = DeployProblem(p.carrier, p.rover, 1.0, (0, 0, 0), 0.0,
                        (Task("near", (0.5, 0, 0)), Task("far", (100, 0, 0))), ("r1", "r2"))
    with pytest.raises(PlanningError, match="far"):
        DEPLOY_PLANNERS["direct"](far)


def test_too_few_rovers_is_an_error():
    p = random_problem(2, 5, False)
    short = DeployProblem(p.carrier, p.rover, p.deploy_range, p.start, p.heading, p.tasks, ("r1", "r2"))
    for name in ("lee", "greedy2opt", "direct"):
        with pytest.raises(PlanningError, match="rovers"):
            DEPLOY_PLANNERS[name](short)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10**6), three_d=st.booleans())
def test_two_task_optimum_is_checked_and_lee_matches_it(seed, three_d):
    p = random_problem(seed, 2, three_d, size=60.0)
    two = check(p, "two-task")
    lee = check(p, "lee")
    assert lee["makespan"] <= two["makespan"] + 1e-3


def test_apollonius_circle():
    g1, g2 = (10.0, 35.0), (40.0, 35.0)
    center, radius = apollonius_circle(g1, g2, 10.0, 2.0)
    for k in range(12):  # every point of the circle: rover to g1 takes as long as carrier to g2
        a = 2 * math.pi * k / 12
        p = (center[0] + radius * math.cos(a), center[1] + radius * math.sin(a))
        assert math.dist(p, g1) / 2.0 == pytest.approx(math.dist(p, g2) / 10.0)
    s = apollonius_point((20.0, 10.0), g1, g2, 10.0, 2.0)
    assert s is not None and 0 < s < 1


def test_table_4_2_delays_move_the_first_stop_toward_the_carrier():
    # Table 4.2: with rotation, acceleration and unloading the first stop lies before the
    # delay-free Apollonius point on the segment carrier → first task (Fig. 4.2).
    p = DeployProblem(CarrierSpec(10.0, 5.0, 2.0, 1.0, 1.0), Motion(2.0), 15.0, (20, 10, 0), math.pi / 2,
                      (Task("t1", (10, 35, 0)), Task("t2", (40, 35, 0))), ("r1", "r2"))
    plan = plan_two_tasks(p)
    first = plan.stops[0].position
    s_old = apollonius_point((20, 10), (10, 35), (40, 35), 10.0, 2.0)
    s_new = math.dist(first[:2], (20, 10)) / math.dist((20, 10), (10, 35))
    assert len(plan.stops) == 2 and s_new < s_old
    # Both rovers arrive (nearly) together: that is what makes two tasks optimal (ch. 4.3.1).
    arrivals = [leg.arrive for leg in plan.legs()]
    assert abs(arrivals[0] - arrivals[1]) < 1e-3


def test_lee_beats_greedy2opt_on_the_15_task_scenario():
    tasks = [(57, 11), (76, 59), (17, 17), (13, 75), (9, 26), (50, 70), (82, 67), (70, 62), (50, 32),
             (80, 10), (25, 21), (92, 93), (12, 45), (63, 28), (72, 54)]
    p = DeployProblem(CarrierSpec(15.0, 10.0, 3.0, 4.0, 4.0), Motion(1.0), 25.0, (52, 60, 0), math.pi / 2,
                      tuple(Task(f"t{i + 1}", (x, y, 0.0)) for i, (x, y) in enumerate(tasks)))
    lee = check(p, "lee")
    greedy = check(p, "greedy2opt")
    assert lee["makespan"] < greedy["makespan"]
    assert len(lee["stops"]) < len(tasks)


def test_same_problem_same_plan():
    p = random_problem(7, 40, True)
    a = DEPLOY_PLANNERS["lee"](p).to_json()
    b = DEPLOY_PLANNERS["lee"](p).to_json()
    a.pop("compute_ms"), b.pop("compute_ms")
    assert a == b


def test_lower_bound_regression_zero_length_tree_edges():
    # A task next to the start makes a zero-weight spanning-tree edge; it must not be dropped.
    p = DeployProblem(CarrierSpec(15.9, 8.34, None, 1.5, 0.9), Motion(2.99), 10.44, (19.4, 59.3, 0.0), -1.8,
                      (Task("t0", (11.4, 55.7, 0.0)), Task("t1", (55.0, 6.1, 0.0))), ("r1", "r2"))
    assert deploy_lower_bound(p) <= DEPLOY_PLANNERS["lee"](p).makespan


def test_mst_length():
    from planners.core.lower_bound import mst_length

    w = [[0, 0, 5, 9], [0, 0, 4, 8], [5, 4, 0, 1], [9, 8, 1, 0]]
    import numpy as np

    assert mst_length(np.array(w, dtype=float)) == 5.0


def test_a_first_hop_of_a_centimetre_is_timed_as_its_json_says() -> None:
    # the carrier turns 82 degrees at 0.58 rad/s to a stop 1.1 cm away: the turn recomputed from
    # positions rounded to 6 decimals was 1.6e-4 s off the plan's (found by the property test)
    plan = check(random_problem(894937, 22, False), "lee")
    assert math.dist(plan["carrier"]["start"], plan["stops"][0]["position"]) < 0.02


def test_the_docs_give_the_decimals_the_plan_json_has() -> None:
    from pathlib import Path

    from planners.core.plan import POSITION_DECIMALS, point_json

    text = (Path(__file__).resolve().parents[2] / "docs" / "plan-json.md").read_text()
    assert f"positions to {POSITION_DECIMALS} decimals, times to 6" in " ".join(text.split())
    assert point_json((1 / 3, 0.0, 0.0))[0] == round(1 / 3, POSITION_DECIMALS) != round(1 / 3, 6)
