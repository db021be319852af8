"""Timed release and the reserve check of a collection round (fleetctl.run.collect_timing)."""

from __future__ import annotations

import math

import pytest

from fleetctl.run.collect_timing import (
    ENERGY_SLACK,
    RELEASE_LEAD,
    CarrierNow,
    RoundClock,
    energy_shortfalls,
    points_ahead,
    release_delay,
)
from planners import COLLECT_PLANNERS
from planners.core.plan import Plan, RoverLeg, Stop
from planners.core.problem import CarrierSpec, CollectProblem, CollectRover, Motion
from planners.core.timing import carrier_leg, remaining_leg_time

CARRIER = CarrierSpec(10.0, 5.0, None, 0.0, 2.0, takeoff_time=1.5, land_time=3.5)
ROVER = Motion(2.0)


def two_stop_plan():
    rovers = (CollectRover("near", (20.0, 5.0, 4.0), 30.0), CollectRover("far", (150.0, 10.0, 4.0), 30.0))
    problem = CollectProblem(CARRIER, ROVER, (0.0, 0.0, 0.0), 0.0, rovers)
    plan = COLLECT_PLANNERS["lee"](problem)
    assert len(plan.stops) == 2
    return problem, plan


def test_on_plan_the_live_eta_is_the_planned_arrival():
    _, plan = two_stop_plan()
    clock = RoundClock(plan, CARRIER, start=100.0)
    at_start = CarrierNow((0.0, 0.0, 0.0), 0.0, 0.0)
    for k, stop in enumerate(plan.stops):
        for leg in stop.rovers:  # released at the start: there at its planned arrival
            clock.rover_ready(k, 100.0 + leg.arrive)
    assert clock.eta(0, 100.0, at_start) == pytest.approx(100.0 + plan.stops[0].arrive, abs=1e-6)
    assert clock.eta(1, 100.0, at_start) == pytest.approx(100.0 + plan.stops[1].arrive, abs=1e-6)
    assert clock.makespan(100.0, at_start) == pytest.approx(100.0 + plan.makespan, abs=1e-6)


def test_a_late_carrier_moves_the_eta_and_the_release_of_the_rovers_waiting():
    _, plan = two_stop_plan()
    clock = RoundClock(plan, CARRIER, start=0.0)
    leg = plan.stops[1].rovers[0]
    on_time = clock.eta(1, 0.0, CarrierNow((0.0, 0.0, 0.0), 0.0, 0.0))
    # 10 s later the carrier has not moved (held up): everything after it is 10 s later
    late = clock.eta(1, 10.0, CarrierNow((0.0, 0.0, 0.0), 0.0, 0.0))
    assert late == pytest.approx(on_time + 10.0, abs=1e-6)
    assert release_delay(late, leg.arrive, 10.0) == pytest.approx(
        release_delay(on_time, leg.arrive, 0.0), abs=1e-6)
    # part-way along its first leg, moving at full speed: the rest of the leg from there
    x = plan.stops[0].position
    half = (x[0] / 2, x[1] / 2, 0.0)
    eta0 = clock.eta(0, 50.0, CarrierNow(half, 10.0, math.atan2(x[1], x[0])))
    rest = remaining_leg_time(math.dist(half, x), 10.0, CARRIER.motion)
    assert eta0 == pytest.approx(50.0 + rest, abs=1e-6)
    clock.reached(0, 60.0)
    assert clock.eta(0, 70.0, None) == 60.0  # an arrival, once seen, is fixed


def test_a_rover_is_released_to_meet_the_carrier_not_to_wait_for_it():
    _, plan = two_stop_plan()
    clock = RoundClock(plan, CARRIER, start=0.0)
    now, here = 0.0, CarrierNow((0.0, 0.0, 0.0), 0.0, 0.0)
    for k, stop in enumerate(plan.stops):
        for leg in stop.rovers:
            wait = release_delay(clock.eta(k, now, here), leg.arrive, now)
            # released so that it is above its stop RELEASE_LEAD before the carrier (or at once
            # when its own flight is the longer one)
            assert wait == pytest.approx(max(stop.arrive - leg.arrive - RELEASE_LEAD, 0.0), abs=1e-6)


def test_reserve_check_counts_the_hover_of_a_rover_in_the_air():
    problem, plan = two_stop_plan()
    rovers = problem.rovers
    speed = ROVER.max_speed
    # plenty of battery: nobody short
    rich = {r.id: 10_000.0 for r in rovers}
    assert energy_shortfalls(plan, rich, {"near", "far"}, CARRIER, speed) == []
    # exactly the flight's range: in the air it also hovers until the carrier is there -> short;
    # on the ground it waits for free
    tight = {leg.rover: (leg.arrive + RELEASE_LEAD + CARRIER.land_time + ENERGY_SLACK) * speed
             for stop in plan.stops for leg in stop.rovers}
    in_air = energy_shortfalls(plan, tight, {"near", "far"}, CARRIER, speed)
    assert {s.rover for s in in_air} == {leg.rover for s in plan.stops for leg in s.rovers
                                         if max(s.arrive, leg.arrive) > leg.arrive + RELEASE_LEAD}
    assert all(s.airborne > s.allowed for s in in_air)
    assert energy_shortfalls(plan, tight, set(), CARRIER, speed) == []
    # ENERGY_SLACK is kept in hand: a battery just short of it is short
    short = {r: m - 0.5 * ENERGY_SLACK * speed for r, m in tight.items()}
    assert {s.rover for s in energy_shortfalls(plan, short, set(), CARRIER, speed)} == set(tight)


ROAD = CarrierSpec(10.0, 5.0, 1.0, 0.0, 2.0, takeoff_time=1.5, land_time=3.5, vertex_stops=True)


def _roadmap_plan() -> Plan:
    """One stop reached along a roadmap path with two corners: the carrier stops at each vertex
    and turns there (docs/time-model.md)."""
    path = [(0.0, 0.0, 0.0), (20.0, 0.0, 0.0), (20.0, 15.0, 0.0), (28.0, 15.0, 0.0)]
    arrive, _ = carrier_leg(path, 0.0, ROAD)
    leg = RoverLeg("r1", [(28.0, 20.0, 4.0), (28.0, 15.0, 3.0)], arrive - 1.0)
    stop = Stop(path[-1], path, [leg], arrive, arrive + ROAD.collect_stop_time)
    return Plan("collect", "test", path[0], 0.0, [stop], makespan=stop.depart)


def test_on_a_roadmap_the_eta_counts_a_stop_and_a_turn_at_every_vertex_ahead():
    plan = _roadmap_plan()
    clock = RoundClock(plan, ROAD, start=5.0)
    rest_of_path = carrier_leg([(20.0, 0.0, 0.0), (20.0, 15.0, 0.0), (28.0, 15.0, 0.0)], 0.0, ROAD)[0]
    after_corner = carrier_leg([(20.0, 15.0, 0.0), (28.0, 15.0, 0.0)], math.pi / 2, ROAD)[0]
    # at rest at the start: the planned arrival
    at_start = clock.eta(0, 5.0, CarrierNow((0.0, 0.0, 0.0), 0.0, 0.0))
    assert at_start == pytest.approx(5.0 + plan.stops[0].arrive)
    # half-way along the first segment at full speed: brakes into the first corner, then the rest
    moving = clock.eta(0, 9.0, CarrierNow((10.0, 0.0, 0.0), 10.0, 0.0))
    assert moving == pytest.approx(9.0 + remaining_leg_time(10.0, 10.0, ROAD.motion) + rest_of_path)
    # just past the first corner, heading north: not back to the corner behind it
    past = clock.eta(0, 12.0, CarrierNow((20.0, 1.0, 0.0), 2.0, math.pi / 2))
    assert past == pytest.approx(12.0 + remaining_leg_time(14.0, 2.0, ROAD.motion) + after_corner)
    # at rest on the first corner, still facing east: turns north, then drives on
    corner = clock.eta(0, 12.0, CarrierNow((20.0, 0.0, 0.0), 0.0, 0.0))
    assert corner == pytest.approx(12.0 + rest_of_path)


def test_the_vertices_ahead_of_a_carrier():
    path = [(0.0, 0.0, 0.0), (20.0, 0.0, 0.0), (20.0, 15.0, 0.0)]
    assert points_ahead((5.0, 0.2, 0.0), path, path[-1]) == path[1:]
    assert points_ahead((20.0, 0.0, 0.0), path, path[-1]) == path[2:]  # at a vertex: the segment leaving it
    assert points_ahead((19.0, 9.0, 0.0), path, path[-1]) == path[2:]
    assert points_ahead((3.0, 4.0, 0.0), [], (9.0, 9.0, 0.0)) == [(9.0, 9.0, 0.0)]  # a straight leg
