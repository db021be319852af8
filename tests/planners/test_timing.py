"""The time model (docs/time-model.md, eq. 4.2/4.3/5.2) against hand-computed values."""

import math

import pytest

from planners.core.plan import Plan, RoverLeg, Stop
from planners.core.problem import CarrierSpec, Motion
from planners.core.timing import (
    carrier_leg,
    collect_schedule,
    deploy_schedule,
    heading_change,
    leg_time,
    retime,
    turn_time,
)


def test_leg_reaches_top_speed():
    # S = 100 >= v²/a = 225/10 = 22.5: S/v + v/a = 6.6667 + 1.5
    assert leg_time(100.0, Motion(15.0, 10.0)) == pytest.approx(100 / 15 + 1.5)


def test_leg_too_short_for_top_speed():
    # S = 10 < 22.5: 2·sqrt(S/a) = 2·1 = 2
    assert leg_time(10.0, Motion(15.0, 10.0)) == pytest.approx(2.0)


def test_leg_branches_meet_at_the_threshold():
    m = Motion(15.0, 10.0)
    s = 15.0**2 / 10.0
    assert leg_time(s - 1e-9, m) == pytest.approx(leg_time(s, m), abs=1e-6)
    assert leg_time(s, m) == pytest.approx(2 * 15 / 10)


def test_constant_speed_and_zero_length():
    assert leg_time(30.0, Motion(2.0, None)) == pytest.approx(15.0)
    assert leg_time(0.0, Motion(2.0, 1.0)) == 0.0


def test_rotation():
    assert heading_change(0.1, 2 * math.pi - 0.1) == pytest.approx(0.2)
    assert heading_change(0.0, math.pi) == pytest.approx(math.pi)
    assert turn_time(0.0, math.pi / 2, 2.0) == pytest.approx(math.pi / 4)
    assert turn_time(0.0, math.pi / 2, None) == 0.0


def test_carrier_leg_turns_at_the_start_only():
    c = CarrierSpec(max_speed=10.0, accel=None, turn_rate=1.0)
    # heading east, leg goes north then east: turn π/2 at the start (charged), π/2 at the vertex (not)
    t, h = carrier_leg([(0, 0, 0), (0, 10, 0), (10, 10, 0)], 0.0, c)
    assert t == pytest.approx(math.pi / 2 + 2.0)
    assert h == pytest.approx(0.0)


def test_deploy_schedule_by_hand():
    c = CarrierSpec(max_speed=10.0, accel=5.0, turn_rate=2.0, unload_time=1.0)
    r = Motion(2.0)
    # start (0,0) heading north; stop 1 at (0, 40): no turn, S = 40 >= 20: 4 + 2 = 6 s; unload 1
    # stop 2 at (10, 40): turn π/2 → π/4 s, S = 10 < 20: 2·sqrt(2) s; unload 1
    paths = [[(0, 0, 0), (0, 40, 0)], [(0, 40, 0), (10, 40, 0)]]
    lengths = [[6.0], [4.0, 0.0]]
    arrive, depart, rovers, makespan = deploy_schedule((0, 0, 0), math.pi / 2, paths, lengths, c, r)
    assert arrive[0] == pytest.approx(6.0)
    assert depart[0] == pytest.approx(7.0)
    assert rovers[0][0] == pytest.approx(10.0)
    assert arrive[1] == pytest.approx(7.0 + math.pi / 4 + 2 * math.sqrt(2))
    assert depart[1] == pytest.approx(arrive[1] + 1.0)
    assert rovers[1] == pytest.approx([depart[1] + 2.0, depart[1]])
    assert makespan == pytest.approx(max(10.0, depart[1] + 2.0))


def test_collect_schedule_waits_for_late_rovers():
    c = CarrierSpec(max_speed=10.0, accel=None, turn_rate=None, load_time=2.0)
    r = Motion(1.0)
    paths = [[(0, 0, 0), (10, 0, 0)], [(10, 0, 0), (20, 0, 0)]]
    # stop 1: carrier at 1 s, rover arrives at 5 s → eta 7; stop 2: carrier 8 s, rover 3 s → eta 10
    arrive, depart, rovers, makespan = collect_schedule((0, 0, 0), 0.0, paths, [[5.0], [3.0]], c, r)
    assert arrive == pytest.approx([1.0, 8.0])
    assert depart == pytest.approx([7.0, 10.0])
    assert makespan == pytest.approx(10.0)


def test_retime_fills_a_plan():
    c = CarrierSpec(max_speed=10.0, accel=None, turn_rate=None, unload_time=1.0)
    stop = Stop(position=(10, 0, 0), carrier_path=[(0, 0, 0), (10, 0, 0)],
                rovers=[RoverLeg("r1", [(10, 0, 0), (10, 3, 4)], task="t1")])
    plan = retime(Plan("deploy", "x", (0, 0, 0), 0.0, [stop]), c, Motion(1.0))
    assert plan.makespan == pytest.approx(1.0 + 1.0 + 5.0)
    assert plan.carrier_distance == pytest.approx(10.0)


def test_carrier_hop_agrees_with_carrier_leg():
    import random

    from planners.core.timing import carrier_hop

    rng = random.Random(3)
    for _ in range(500):
        c = CarrierSpec(rng.uniform(1, 20), rng.choice([None, rng.uniform(0.5, 10)]),
                        rng.choice([None, rng.uniform(0.2, 4)]))
        p = (rng.uniform(-50, 50), rng.uniform(-50, 50), 0.0)
        q = p if rng.random() < 0.1 else (rng.uniform(-50, 50), rng.uniform(-50, 50), 0.0)
        h = rng.uniform(-7, 7)
        t1, h1 = carrier_hop(p, q, h, c)
        t2, h2 = carrier_leg([p, q], h, c)
        assert t1 == pytest.approx(t2, rel=1e-12, abs=1e-12) and h1 == pytest.approx(h2)


def test_fixed_time_is_added_to_every_rover_flight_and_not_to_the_carrier():
    from planners.core.problem import CarrierSpec, Motion
    from planners.core.timing import carrier_leg, leg_time, travel_time

    rover = Motion(2.0, 1.0, fixed_time=1.5)
    for length in (0.0, 0.5, 4.0, 30.0):
        assert leg_time(length, rover) == pytest.approx(1.5 + travel_time(length, Motion(2.0, 1.0)))
    carrier = CarrierSpec(10.0, 5.0, 1.0)
    t, _ = carrier_leg([(0.0, 0.0, 0.0), (50.0, 0.0, 0.0)], 0.0, carrier)
    assert t == pytest.approx(travel_time(50.0, carrier.motion))


def test_dissertation_model_drops_the_fixed_time_and_shifts_a_deployment_by_it():
    from planners import DEPLOY_PLANNERS
    from planners.core.problem import CarrierSpec, DeployProblem, Motion, Task
    from planners.core.timing import dissertation_model

    tasks = tuple(Task(f"t{i}", (10.0 * i, 5.0 * (i % 3), 2.0)) for i in range(6))
    p = DeployProblem(CarrierSpec(10.0, 5.0, 1.0, 2.0, 2.0), Motion(2.0, None, fixed_time=3.0), 15.0,
                      (0.0, 0.0, 0.0), 0.0, tasks)
    base = dissertation_model(p)
    assert base.rover.fixed_time == 0.0 and dissertation_model(base) is base
    p2 = DeployProblem(CarrierSpec(10.0, 5.0, 1.0, 2.0, 2.0, takeoff_time=1.0), Motion(2.0), 15.0,
                       (0.0, 0.0, 0.0), 0.0, tasks)
    first = DEPLOY_PLANNERS["lee"](p2).stops[0]
    assert first.depart == pytest.approx(first.arrive + 3.0)  # unload 2 s + take-off clearance 1 s
    a, b = DEPLOY_PLANNERS["lee"](p), DEPLOY_PLANNERS["lee"](base)
    # in a deployment the fixed time is a constant on every rover arrival: same plan, makespan + 3 s
    assert a.makespan == pytest.approx(b.makespan + 3.0)


@pytest.mark.parametrize("accel", [None, 0.5, 3.0])
def test_remaining_leg_time_matches_the_leg_from_rest_and_a_simulated_profile(accel):
    from planners.core.problem import Motion
    from planners.core.timing import remaining_leg_time, travel_time

    m = Motion(4.0, accel)
    for d in (0.5, 3.0, 40.0):
        assert remaining_leg_time(d, 0.0, m) == pytest.approx(travel_time(d, m))
    if accel is None:
        return
    # integrate the profile from a speed v0 part-way: accelerate, cruise, brake to rest at the end
    for d, v0 in ((40.0, 2.0), (5.0, 3.0), (30.0, 4.0)):
        x, v, t, dt = 0.0, v0, 0.0, 1e-4
        while d - x > 1e-6 and t < 100:
            v = max(min(4.0, v + accel * dt, math.sqrt(2 * accel * (d - x))), 1e-3)
            x += v * dt
            t += dt
        assert remaining_leg_time(d, v0, m) == pytest.approx(t, rel=0.02)


def test_vertex_stops_drive_a_polyline_as_rest_to_rest_segments_with_turns():
    from planners.core.problem import CarrierSpec
    from planners.core.timing import carrier_hop, carrier_leg

    path = [(0.0, 0.0, 0.0), (30.0, 0.0, 0.0), (30.0, 40.0, 0.0), (0.0, 40.0, 0.0)]
    one = CarrierSpec(10.0, 5.0, 1.0)
    stops = CarrierSpec(10.0, 5.0, 1.0, vertex_stops=True)
    t_one, h_one = carrier_leg(path, 0.0, one)
    t_stops, h_stops = carrier_leg(path, 0.0, stops)
    expect, h = 0.0, 0.0
    for p, q in zip(path, path[1:], strict=False):
        dt, h = carrier_hop(p, q, h, stops)
        expect += dt
    assert t_stops == pytest.approx(expect) and h_stops == pytest.approx(h_one)
    # two π/2 turns at 1 rad/s and two extra accelerations (v/a = 2 s each) over one 110 m leg
    assert t_stops == pytest.approx(t_one + math.pi + 2 * 2.0)
    assert carrier_leg(path[:2], 0.0, stops) == carrier_leg(path[:2], 0.0, one)  # a straight leg


def test_numpy_forms_agree_with_carrier_step_and_leg_time():
    """carrier_steps / travel_times / leg_times (the planners' batch scoring) give carrier_step's
    and leg_time's numbers, zero-length hops (heading kept, no turn) included."""
    import random

    import numpy as np

    from planners.core.timing import carrier_step, carrier_steps, leg_time, leg_times

    rng = random.Random(5)
    for _ in range(60):
        c = CarrierSpec(rng.uniform(1, 20), rng.choice([None, rng.uniform(0.5, 10)]),
                        rng.choice([None, rng.uniform(0.2, 4)]))
        m = Motion(rng.uniform(1, 5), rng.choice([None, rng.uniform(0.5, 5)]), rng.uniform(0, 3))
        dx = np.array([rng.uniform(-60, 60) if rng.random() > 0.1 else 0.0 for _ in range(40)])
        dy = np.array([rng.uniform(-60, 60) if x else 0.0 for x in dx])
        h0 = np.array([rng.uniform(-7, 7) for _ in range(40)])
        t, h = carrier_steps(dx, dy, h0, c)
        lengths = np.hypot(dx, dy)
        legs = leg_times(lengths, m)
        for i in range(40):
            t1, h1 = carrier_step(float(dx[i]), float(dy[i]), float(h0[i]), c)
            assert t[i] == pytest.approx(t1, rel=1e-12, abs=1e-12) and h[i] == pytest.approx(h1, abs=1e-12)
            assert legs[i] == pytest.approx(leg_time(float(lengths[i]), m), rel=1e-12, abs=1e-12)


def test_bound_forms_give_carrier_step_carrier_hop_and_leg_time_bit_for_bit():
    """carrier_stepper / carrier_hopper / leg_timer (the planners' innermost loops) return exactly
    the floats of carrier_step, carrier_hop and leg_time (plans must not change with them), on
    both branches of eq. 4.2, at the ramp's threshold, for zero-length hops and half turns."""
    import random

    from planners.core.timing import carrier_hop, carrier_hopper, carrier_step, carrier_stepper, leg_timer

    rng = random.Random(11)
    for _ in range(80):
        c = CarrierSpec(rng.uniform(1, 20), rng.choice([None, rng.uniform(0.5, 10)]),
                        rng.choice([None, rng.uniform(0.2, 4)]))
        m = Motion(rng.uniform(1, 5), rng.choice([None, rng.uniform(0.5, 5)]), rng.uniform(0, 3))
        step, hop, leg = carrier_stepper(c), carrier_hopper(c), leg_timer(m)
        ramp = c.max_speed ** 2 / c.accel if c.accel else 1.0
        lengths = [0.0, -1.0, ramp, m.max_speed ** 2 / m.accel if m.accel else 2.0,
                   *(rng.uniform(0, 80) for _ in range(30))]
        for length in lengths:
            assert leg(length) == leg_time(length, m)
            a = rng.uniform(-math.pi, math.pi)
            dx, dy = length * math.cos(a), length * math.sin(a)
            h0 = rng.choice([a + math.pi, a - math.pi, rng.uniform(-7, 7)])
            assert step(dx, dy, h0) == carrier_step(dx, dy, h0, c)
            p = (rng.uniform(-50, 50), rng.uniform(-50, 50))
            q = (p[0] + dx, p[1] + dy)
            assert hop(p, q, h0) == carrier_hop(p, q, h0, c)
