"""World kinematics, battery and loading/unloading, without any network."""

from __future__ import annotations

import math

import pytest

from sitl import LOAD_RADIUS, Phase, VehicleSpec, World

DT = 0.05


def world(*, carrier_accel: float | None = 5.0, turn_rate: float | None = None,
          rover_accel: float | None = None, endurance: float | None = 60.0, heading_deg: float = 90.0,
          n: int = 1) -> World:
    carrier = VehicleSpec(id="c", sysid=1, role="carrier", max_speed=10.0, accel=carrier_accel,
                          turn_rate=turn_rate, position=(0.0, 0.0, 0.0), heading_deg=heading_deg,
                          frame="ground")
    rovers = [VehicleSpec(id=f"r{k + 1}", sysid=11 + k, role="rover", max_speed=2.0, accel=rover_accel,
                          endurance_range=endurance) for k in range(n)]
    return World(carrier, rovers)


def run_until(w: World, cond, limit: float = 600.0) -> float:
    t0 = w.time
    while not cond():
        w.step(DT)
        assert w.time - t0 < limit, "condition never reached"
    return w.time - t0


@pytest.mark.parametrize("dist", [100.0, 4.0])
def test_carrier_leg_time_matches_the_time_model(dist: float) -> None:
    w = world(carrier_accel=5.0)
    w.carrier.goto(dist, 0.0)
    t = run_until(w, lambda: w.carrier.arrived)
    v, a = 10.0, 5.0
    expected = dist / v + v / a if dist >= v * v / a else 2 * math.sqrt(dist / a)
    assert t == pytest.approx(expected, abs=3 * DT)
    assert w.carrier.position == pytest.approx((dist, 0.0, 0.0))


def test_carrier_constant_speed_and_turn_on_the_spot() -> None:
    w = world(carrier_accel=None, turn_rate=1.0, heading_deg=0.0)  # facing north
    w.carrier.goto(50.0, 0.0)  # east: a quarter turn first
    t = run_until(w, lambda: w.carrier.arrived)
    assert t == pytest.approx(math.pi / 2 / 1.0 + 50.0 / 10.0, abs=2 * DT)
    assert math.degrees(w.carrier.heading) == pytest.approx(0.0, abs=1e-6)


def test_loaded_rover_rides_with_the_carrier() -> None:
    w = world()
    r = w.rovers["r1"]
    assert r.loaded and r.phase is Phase.LOADED
    w.carrier.goto(30.0, 0.0)
    run_until(w, lambda: w.carrier.arrived)
    assert r.position == pytest.approx((30.0, 0.0, 0.0))
    assert r.battery == 1.0  # riding does not use the battery


def test_takeoff_detaches_and_landing_on_the_stopped_carrier_loads() -> None:
    w = world()
    r = w.rovers["r1"]
    assert r.takeoff(5.0)
    assert r.phase is Phase.AIR and not r.loaded
    run_until(w, lambda: r.arrived)
    assert r.position == pytest.approx((0.0, 0.0, 5.0))
    w.carrier.goto(20.0, 0.0)  # the carrier drives away; the rover stays
    run_until(w, lambda: w.carrier.arrived)
    assert r.position == pytest.approx((0.0, 0.0, 5.0))
    r.goto(20.0 + LOAD_RADIUS * 0.9, 0.0, 5.0)
    run_until(w, lambda: r.arrived)
    r.land()
    run_until(w, lambda: r.on_ground)
    assert r.loaded
    assert "loaded" in r.events and "touchdown" in r.events
    assert r.position == pytest.approx(w.carrier.position)


def test_landing_away_from_the_carrier_stays_on_the_ground() -> None:
    w = world()
    r = w.rovers["r1"]
    r.takeoff(2.0)
    run_until(w, lambda: r.arrived)
    r.land(LOAD_RADIUS + 0.5, 0.0)  # fly there, then land
    run_until(w, lambda: r.on_ground)
    assert r.phase is Phase.GROUND
    assert r.position == pytest.approx((LOAD_RADIUS + 0.5, 0.0, 0.0))
    w.carrier.goto(10.0, 0.0)
    run_until(w, lambda: w.carrier.arrived)
    assert r.position == pytest.approx((LOAD_RADIUS + 0.5, 0.0, 0.0))


def test_landing_on_a_moving_carrier_does_not_load() -> None:
    w = world(carrier_accel=None)
    r = w.rovers["r1"]
    r.takeoff(0.5)
    run_until(w, lambda: r.arrived)
    w.carrier.goto(1000.0, 0.0, speed=0.5)  # slow: still within the load radius at touchdown
    w.step(DT)
    r.land()
    run_until(w, lambda: r.on_ground)
    assert math.dist(r.position[:2], w.carrier.position[:2]) < LOAD_RADIUS
    assert r.phase is Phase.GROUND


def test_hovering_costs_the_battery_as_flying_does() -> None:
    w = world(endurance=60.0)
    r = w.rovers["r1"]
    r.takeoff(10.0)
    run_until(w, lambda: r.arrived)
    before, t0 = r.battery, w.time
    while w.time < t0 + 6.0 - 1e-9:  # hover 6 s at a cruise speed of max_speed: 6·v metres' worth
        w.step(DT)
    assert r.flown == pytest.approx(10.0, abs=1e-6)
    assert before - r.battery == pytest.approx((w.time - t0) * r.spec.max_speed / 60.0, rel=1e-6)
    w2 = world(endurance=60.0)
    on_deck = w2.rovers["r1"]
    for _ in range(100):
        w2.step(DT)
    assert on_deck.battery == 1.0  # on the deck it uses none


def test_battery_drains_with_distance_flown() -> None:
    w = world(endurance=60.0)
    r = w.rovers["r1"]
    r.takeoff(10.0)
    run_until(w, lambda: r.arrived)
    r.goto(20.0, 0.0, 10.0)
    run_until(w, lambda: r.arrived)
    assert r.flown == pytest.approx(30.0, abs=1e-6)
    assert r.battery == pytest.approx(1.0 - 30.0 / 60.0, abs=1e-6)


def test_drain_factor_and_empty_battery_lands_where_it_is() -> None:
    w = world(endurance=60.0)
    r = w.rovers["r1"]
    r.drain_factor = lambda: 2.0
    r.takeoff(5.0)
    run_until(w, lambda: r.arrived)
    assert r.battery == pytest.approx(1.0 - 2 * 5.0 / 60.0, abs=1e-6)
    r.goto(100.0, 0.0, 5.0)  # 30 m of battery left at factor 2: 25 m horizontally after the climb
    run_until(w, lambda: r.on_ground)
    assert "battery_empty" in r.events
    assert r.battery == 0.0
    x, y, z = r.position
    assert z == 0.0 and r.phase is Phase.GROUND
    assert x == pytest.approx(25.0, abs=2 * DT * 2.0)
    assert not r.takeoff(5.0)  # an empty battery cannot lift off


@pytest.mark.parametrize("land_travel", [0.0, 1.2])
def test_a_rover_sent_down_while_moving_travels_on_its_land_travel(land_travel: float) -> None:
    """Sent down at 2 m/s, a rover comes down ``land_travel`` s of its speed further on (PX4's
    LAND mode: 1.2 s), or where it brakes to a stop at its acceleration (0: ArduCopter's)."""
    w = world(rover_accel=4.0)
    r = w.rovers["r1"]
    r.land_travel = land_travel
    r.takeoff(3.0)
    run_until(w, lambda: r.arrived)
    r.goto(10.0, 0.0, 3.0)  # away from the deck: it comes down on the ground
    run_until(w, lambda: r.arrived)
    r.goto(40.0, 0.0, 3.0)
    run_until(w, lambda: r.speed >= 2.0)
    x0 = r.position[0]
    r.land()
    run_until(w, lambda: r.on_ground)
    travel = 2.0 * land_travel if land_travel else 2.0**2 / (2 * 4.0)
    assert r.position[0] - x0 == pytest.approx(travel, abs=2.0 * DT)
    assert r.position[1] == pytest.approx(0.0)


def test_rover_acceleration_profile() -> None:
    w = world(rover_accel=1.0)
    r = w.rovers["r1"]
    r.takeoff(1.0)
    run_until(w, lambda: r.arrived)
    r.goto(40.0, 0.0, 1.0)
    t = run_until(w, lambda: r.arrived)
    assert t == pytest.approx(40.0 / 2.0 + 2.0 / 1.0, abs=3 * DT)


def test_world_is_deterministic() -> None:
    def trace() -> list[tuple[float, ...]]:
        w = world(n=3, rover_accel=0.5)
        for k, r in enumerate(w.rovers.values()):
            r.takeoff(2.0 + k)
        w.carrier.goto(15.0, 5.0)
        out = []
        for i in range(400):
            w.step(DT)
            if i == 100:
                for r in w.rovers.values():
                    r.goto(10.0, 10.0, 3.0)
            out.append(tuple(c for r in w.rovers.values() for c in r.position) + w.carrier.position)
        return out

    assert trace() == trace()


def test_a_waypoint_flown_through_keeps_the_speed_a_final_one_stops() -> None:
    w = world(endurance=None, rover_accel=2.0)
    r = w.rovers["r1"]
    r.takeoff(5.0)
    run_until(w, lambda: r.arrived)
    r.goto(20.0, 0.0, 5.0, through=True)
    run_until(w, lambda: r.passed)
    assert r.speed > 1.0 and r.position == pytest.approx((20.0, 0.0, 5.0))  # no braking there
    r.goto(20.0, 20.0, 5.0)
    run_until(w, lambda: r.arrived)
    assert r.speed == 0.0 and r.position == pytest.approx((20.0, 20.0, 5.0))
