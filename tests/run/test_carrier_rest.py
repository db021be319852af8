"""Where a carrier braking into its stop comes to rest (fleetctl.run.carrier_rest)."""

from __future__ import annotations

import math

import pytest

from fleetctl.run.carrier_rest import SAMPLE, RestPredictor


def brake(p: RestPredictor, speeds: list[float], step: float = SAMPLE) -> None:
    for i, v in enumerate(speeds):
        p.observe(i * step, v)


def test_a_carrier_not_braking_rests_where_it_is() -> None:
    p = RestPredictor(accel=1.0)
    brake(p, [2.0, 2.0, 2.05])  # cruising (a little noise is not braking)
    assert p.braking == 0.0
    assert p.rest((3.0, 4.0), (0.0, 2.0)) == (3.0, 4.0)


def test_braking_moves_the_rest_on_by_the_braking_distance() -> None:
    p = RestPredictor(accel=1.0)
    brake(p, [2.0, 1.7, 1.4])  # 1.5 m/s² shown
    assert p.braking == pytest.approx(1.5)
    x, y = p.rest((0.0, 0.0), (0.6, -0.8))  # 1 m/s heading south-east
    assert math.hypot(x, y) == pytest.approx(1.0 / (2 * 1.5))
    assert (x, y) == pytest.approx((0.6 / 3.0, -0.8 / 3.0))


def test_the_stated_accel_is_the_least_braking_assumed() -> None:
    p = RestPredictor(accel=1.0)
    brake(p, [2.0, 1.9])  # 0.5 m/s² shown: it will brake harder
    assert p.braking == pytest.approx(0.5)
    x, _ = p.rest((0.0, 0.0), (2.0, 0.0))
    assert x == pytest.approx(2.0)  # 2² / (2 · 1.0)


def test_samples_closer_than_the_sample_time_are_ignored() -> None:
    p = RestPredictor(accel=1.0)
    p.observe(0.0, 2.0)
    p.observe(SAMPLE / 2, 0.5)  # too soon: the same sample
    assert p.braking == 0.0
    p.observe(SAMPLE, 1.6)
    assert p.braking == pytest.approx(0.4 / SAMPLE)
    p.observe(2 * SAMPLE, math.nan)  # no speed known: nothing changes
    assert p.braking == pytest.approx(0.4 / SAMPLE)


def test_an_instant_carrier_rests_where_it_is() -> None:
    p = RestPredictor(accel=math.inf)
    brake(p, [2.0, 1.0])
    assert p.rest((1.0, 1.0), (1.0, 0.0)) == pytest.approx((1.0, 1.0))


def test_only_autopilots_measured_to_gain_send_rovers_where_the_carrier_brakes_to() -> None:
    """ArduCopter rovers are sent where the braking carrier will stand; PX4 rovers are not (on PX4
    1.18 SIH each DO_REPOSITION switches the rover to HOLD: docs/autopilots.md)."""
    from fleetctl.mavlink.autopilots import ArduPilot, Px4
    from fleetctl.mavlink.autopilots.generic import GenericAutopilot

    assert ArduPilot().follows_braking_carrier
    assert GenericAutopilot().follows_braking_carrier
    assert not Px4().follows_braking_carrier
