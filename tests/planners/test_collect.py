"""Collection planners (dissertation ch. 5): feasibility, timing and bound properties on random 2D and
3D instances, infeasible rovers, the reach-region geometry and the scenario files."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fleetctl.mission import load_mission
from planners import COLLECT_PLANNERS, collect_lower_bound
from planners.collect.reach import make_region
from planners.collect.two import apollonius_guess
from planners.core.plan import Plan
from planners.core.problem import CarrierSpec, CollectProblem, CollectRover, Motion, PlanningError
from planners.core.timing import path_length, retime

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = sorted((ROOT / "missions" / "paper").glob("collect_*.yaml")) + [ROOT / "missions" / "recon.yaml"]
TOL = 1e-6


# ------------------------------------------------------------- an independent time model (docs/time-model.md)

def _leg(length: float, v: float, a: float | None) -> float:
    if length <= 0:
        return 0.0
    if a is None:
        return length / v
    return length / v + v / a if length >= v * v / a else 2 * math.sqrt(length / a)


def _recompute(js: dict, problem: CollectProblem) -> float:
    """Eq. 5.2 from the plan JSON alone, written from docs/time-model.md (not timing.py): rover
    flights plus the fixed time, a stop's land_time + load_time once carrier and rovers are there."""
    c, r = problem.carrier, problem.rover
    heading, eta = js["carrier"]["heading"], 0.0
    for stop in js["stops"]:
        path = stop["carrier_path"]
        drive = 0.0
        length = sum(math.dist(p, q) for p, q in zip(path, path[1:], strict=False))
        segs = [(q[0] - p[0], q[1] - p[1]) for p, q in zip(path, path[1:], strict=False)
                if math.hypot(q[0] - p[0], q[1] - p[1]) > 1e-9]
        if segs:
            h = math.atan2(segs[0][1], segs[0][0])
            turn = abs((h - heading + math.pi) % (2 * math.pi) - math.pi)
            drive = (0.0 if c.turn_rate is None else turn / c.turn_rate) + _leg(length, c.max_speed, c.accel)
            heading = math.atan2(segs[-1][1], segs[-1][0])
        lengths = [sum(math.dist(p, q) for p, q in zip(leg["path"], leg["path"][1:], strict=False))
                   for leg in stop["rovers"]]
        flights = [r.fixed_time + _leg(length, r.max_speed, r.accel) for length in lengths]
        eta = max([eta + drive, *flights]) + c.land_time + c.load_time
    return eta


def check_plan(problem: CollectProblem, plan: Plan) -> None:
    """Every property a collection plan must have."""
    rovers = {r.id: r for r in problem.rovers}
    js = json.loads(json.dumps(plan.to_json()))
    assert js["kind"] == "collect"
    ids = [leg["rover"] for stop in js["stops"] for leg in stop["rovers"]]
    assert sorted(ids) == sorted(rovers), "every rover collected exactly once"
    prev_depart, prev_pos = 0.0, list(problem.start)
    for stop in js["stops"]:
        assert stop["position"][2] == 0.0
        assert stop["carrier_path"][0] == pytest.approx(prev_pos, abs=1e-6)
        assert stop["carrier_path"][-1] == stop["position"]
        assert stop["arrive"] >= prev_depart - TOL
        latest = stop["arrive"]
        for leg in stop["rovers"]:
            rv = rovers[leg["rover"]]
            assert leg["from"] == pytest.approx(list(rv.position), abs=1e-6)
            # rovers fly to the approach point above the stop and land on the carrier from there
            end = [*stop["position"][:2], problem.approach_height]
            assert leg["path"][-1] == pytest.approx(end, abs=1e-6), "rovers land on the carrier"
            flight = sum(math.dist(p, q) for p, q in zip(leg["path"], leg["path"][1:], strict=False))
            # the JSON rounds coordinates to 1e-6 m: a rover exactly at its range height may read 1e-6 over
            assert flight <= rv.range + 2e-6, f"{rv.id} flies {flight} m with a range of {rv.range} m"
            latest = max(latest, leg["arrive"])
        # the carrier leaves only after its rovers have landed and the load time has passed
        assert stop["depart"] >= latest + problem.carrier.land_time + problem.carrier.load_time - TOL
        prev_depart, prev_pos = stop["depart"], stop["position"]
    for leg in plan.legs():  # unrounded: every flight within its range
        # planned flights stay RANGE_MARGIN inside the range; a rover with (almost) no range left is
        # met where it is, up to the planners' 1e-9 m geometric tolerance
        assert path_length(leg.path) <= rovers[leg.rover].range + 1e-9, leg.rover
    again = retime(copy.deepcopy(plan), problem.carrier, problem.rover)
    assert plan.makespan == pytest.approx(again.makespan, abs=1e-9)
    assert js["makespan"] == pytest.approx(_recompute(js, problem), abs=5e-4)  # JSON rounds to 1e-6 m
    assert collect_lower_bound(problem) <= plan.makespan + 1e-7


# ------------------------------------------------------------------ random instances

@st.composite
def problems(draw: st.DrawFn, three_d: bool) -> CollectProblem:
    n = draw(st.integers(1, 9))
    coord = st.floats(0, 120, allow_nan=False)
    rovers = []
    for i in range(n):
        z = draw(st.floats(0, 10)) if three_d else 0.0
        rng = draw(st.floats(z + 0.0, z + 40))
        rovers.append(CollectRover(f"r{i + 1}", (draw(coord), draw(coord), z), rng))
    accel = draw(st.sampled_from([None, 2.0, 10.0]))
    turn = draw(st.sampled_from([None, 1.0, 4.0]))
    carrier = CarrierSpec(max_speed=draw(st.floats(3, 25)), accel=accel, turn_rate=turn,
                          load_time=draw(st.floats(0, 6)))
    rover = Motion(draw(st.floats(0.5, 8)), draw(st.sampled_from([None, 3.0])))
    start = (draw(coord), draw(coord), 0.0)
    return CollectProblem(carrier, rover, start, draw(st.floats(-math.pi, math.pi)), tuple(rovers))


@pytest.mark.parametrize("name", sorted(COLLECT_PLANNERS))
def test_a_stop_a_hair_from_one_that_cannot_move_is_put_on_it(name: str) -> None:
    """Two rovers at one place, one with no range left (met exactly there): the stops of a plan
    that serves them one after the other were 0.8 nm apart, a hop whose heading the JSON's rounding
    made up (its turn cost 0.46 s that the plan did not count). Found by test_random_instances."""
    problem = CollectProblem(
        carrier=CarrierSpec(max_speed=3.0, accel=2.0, turn_rate=1.0), rover=Motion(max_speed=1.0),
        start=(0.0, 1.0, 0.0), heading=0.0,
        rovers=(CollectRover(id="r1", position=(2.0, 0.0, 0.0), range=0.0),
                CollectRover(id="r2", position=(2.0, 0.0, 0.0), range=1.0)))
    plan = COLLECT_PLANNERS[name](problem)
    check_plan(problem, plan)
    stops = [s.position for s in plan.stops]
    assert all(a == b or math.dist(a, b) >= 1e-2 for a, b in zip(stops, stops[1:], strict=False)), stops


@pytest.mark.parametrize("name", sorted(COLLECT_PLANNERS))
@pytest.mark.parametrize("three_d", [False, True], ids=["2d", "3d"])
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_random_instances(name: str, three_d: bool, data: st.DataObject) -> None:
    problem = data.draw(problems(three_d))
    check_plan(problem, COLLECT_PLANNERS[name](problem))


def _grid(n: int, seed: int, size: float = 200.0) -> CollectProblem:
    rng = np.random.default_rng(seed)
    rovers = tuple(CollectRover(f"r{i + 1}", (*rng.uniform(0, size, 2), float(rng.uniform(0, 5))),
                                float(rng.uniform(6, 25))) for i in range(n))
    carrier = CarrierSpec(15.0, 5.0, 3.0, 0.0, 3.0)
    return CollectProblem(carrier, Motion(3.0), (100.0, 100.0, 0.0), 0.3, rovers)


@pytest.mark.parametrize("name", sorted(COLLECT_PLANNERS))
def test_larger_instance(name: str) -> None:
    problem = _grid(40, seed=7)
    check_plan(problem, COLLECT_PLANNERS[name](problem))


def test_lee_beats_visit_all_on_a_crowd() -> None:
    """Clustering pays when many rovers can share a stop (ch. 5.6.2)."""
    problem = _grid(60, seed=3, size=120.0)
    lee = COLLECT_PLANNERS["lee"](problem).makespan
    assert lee < COLLECT_PLANNERS["visit-all"](problem).makespan
    assert COLLECT_PLANNERS["lee-convex"](problem).makespan <= lee + 1e-9  # it only polishes lee's route


def test_rovers_that_can_meet_share_a_stop() -> None:
    """Two slow rovers 10 m apart with plenty of range, a long load time: one stop for both."""
    rovers = (CollectRover("a", (50.0, 0.0, 0.0), 30.0), CollectRover("b", (60.0, 0.0, 0.0), 30.0))
    carrier = CarrierSpec(10.0, None, None, 0.0, 20.0)
    problem = CollectProblem(carrier, Motion(1.0), (0.0, 0.0, 0.0), 0.0, rovers)
    for name in ("lee", "lee-convex"):
        plan = COLLECT_PLANNERS[name](problem)
        assert len(plan.stops) == 1
        check_plan(problem, plan)


def test_two_rovers_never_worse_than_visiting_both() -> None:
    for seed in range(6):
        problem = _grid(2, seed=seed, size=80.0)
        lee, visit = COLLECT_PLANNERS["lee"](problem), COLLECT_PLANNERS["visit-all"](problem)
        assert lee.makespan <= visit.makespan + 1e-9


def test_apollonius_guess_is_a_simultaneous_meeting() -> None:
    start, first, other = (0.0, 0.0), (30.0, 20.0), (60.0, -10.0)
    p = apollonius_guess(start, first, other, 10.0, 2.0)
    assert p is not None
    assert math.dist(p, start) / 10.0 == pytest.approx(math.dist(p, first) / 2.0)
    assert apollonius_guess(start, first, other, 2.0, 2.0) is None


# ------------------------------------------------------------------ infeasible rovers

@pytest.mark.parametrize("name", sorted(COLLECT_PLANNERS))
def test_infeasible_rover_is_named(name: str) -> None:
    rovers = (CollectRover("r1", (10.0, 10.0, 2.0), 9.0), CollectRover("weak7", (40.0, 5.0, 12.0), 8.0))
    problem = CollectProblem(CarrierSpec(10.0), Motion(1.0), (0.0, 0.0, 0.0), 0.0, rovers)
    with pytest.raises(PlanningError, match=r"weak7.*12 m up with only 8 m of range"):
        COLLECT_PLANNERS[name](problem)
    with pytest.raises(PlanningError, match="weak7"):
        collect_lower_bound(problem)


def test_rover_exactly_at_its_range_height_lands_below() -> None:
    rovers = (CollectRover("r1", (20.0, 0.0, 8.0), 8.0), CollectRover("r2", (25.0, 3.0, 0.0), 10.0))
    problem = CollectProblem(CarrierSpec(10.0, 3.0, 2.0, 0.0, 2.0), Motion(1.0), (0.0, 0.0, 0.0), 0.0, rovers)
    for name, planner in COLLECT_PLANNERS.items():
        plan = planner(problem)
        check_plan(problem, plan)
        leg = next(leg for leg in plan.legs() if leg.rover == "r1")
        assert leg.end[:2] == pytest.approx((20.0, 0.0), abs=1e-9), name


# ------------------------------------------------------------------ reach regions

@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 50), st.floats(0, 50), st.floats(0.5, 30)), min_size=1, max_size=7),
       st.tuples(st.floats(-20, 70), st.floats(-20, 70)))
def test_region_feasibility_and_projection(discs: list[tuple[float, float, float]],
                                           p: tuple[float, float]) -> None:
    ground = np.array([[x, y] for x, y, _ in discs])
    radii = np.array([r for *_, r in discs])
    reg = make_region(range(len(discs)), ground, radii, np.zeros(len(discs)))
    pair_ok = all(math.dist(a[:2], b[:2]) <= a[2] + b[2] + 1e-9 for a in discs for b in discs)
    if not pair_ok:
        assert not reg.feasible
    if len(discs) <= 2:
        assert reg.feasible == pair_ok
    if not reg.feasible:
        return
    assert reg.contains(reg.center, 1e-7)
    q = reg.project(p)
    assert reg.contains(q, 1e-7)
    # no point of the region (sampled between the centre and the vertices) is nearer to p
    samples = [reg.center, reg.time_center, *reg.vertex_list]
    for a in samples:
        for s in np.linspace(0, 1, 5):
            x = (reg.center[0] + s * (a[0] - reg.center[0]), reg.center[1] + s * (a[1] - reg.center[1]))
            assert math.dist(q, p) <= math.dist(x, p) + 1e-6


# ------------------------------------------------------------------ scenario files

@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_scenario_files_plan_with_every_planner(path: Path) -> None:
    problem = load_mission(path).collect_problem()
    for name, planner in COLLECT_PLANNERS.items():
        plan = planner(problem)
        assert plan.planner == name
        check_plan(problem, plan)


def test_flights_end_at_the_approach_point_and_keep_their_times():
    from planners.core.approach import lifted
    from planners.core.timing import path_length

    rovers = (CollectRover("a", (30.0, 5.0, 8.0), 40.0), CollectRover("b", (60.0, -10.0, 0.0), 40.0))
    base = CollectProblem(CarrierSpec(10.0, 5.0, None, 0.0, 2.0), Motion(2.0), (0.0, 0.0, 0.0), 0.0, rovers)
    up = dataclasses.replace(base, approach_height=3.0)
    plan = COLLECT_PLANNERS["lee"](up)
    lift = COLLECT_PLANNERS["lee"](lifted(up))
    assert plan.makespan == pytest.approx(lift.makespan, abs=1e-9)
    start = {r.id: r.position for r in rovers}
    for stop in plan.stops:
        for leg in stop.rovers:
            assert leg.path[0] == pytest.approx(start[leg.rover])
            assert leg.path[-1] == pytest.approx((stop.position[0], stop.position[1], 3.0))
            # the flight to the point 3 m above the stop: shorter than to the deck from 8 m up,
            # longer (a climb) from the ground
            to_deck = math.dist(start[leg.rover], stop.position)
            assert (path_length(leg.path) < to_deck) == (start[leg.rover][2] > 1.5)
    assert plan.to_json()["time_model"]["approach_height"] == 3.0
    assert collect_lower_bound(up) <= plan.makespan + 1e-7
    again = retime(copy.deepcopy(plan), up.carrier, up.rover)
    assert again.makespan == pytest.approx(plan.makespan, abs=1e-9)
