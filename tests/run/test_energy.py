"""fleetctl.run.energy: range = (remaining - reserve) · endurance_range, clamped at 0."""

from __future__ import annotations

import math

import pytest

from fleetctl.run.energy import battery_range, range_from_percent


@pytest.mark.parametrize(("remaining", "reserve", "endurance", "expected"), [
    (1.0, 0.1, 60.0, 54.0),
    (0.5, 0.1, 60.0, 24.0),
    (0.1, 0.1, 60.0, 0.0),
    (0.05, 0.1, 60.0, 0.0),  # below the reserve: nothing to plan with
    (1.5, 0.0, 10.0, 10.0),  # more than full is full
    (-0.2, 0.0, 10.0, 0.0),
])
def test_battery_range(remaining: float, reserve: float, endurance: float, expected: float) -> None:
    assert battery_range(remaining, reserve, endurance) == pytest.approx(expected)


def test_range_from_percent() -> None:
    assert range_from_percent(75.0, 0.1, 60.0) == pytest.approx(39.0)
    assert range_from_percent(None, 0.1, 60.0) is None


@pytest.mark.parametrize(("args", "what"), [((0.5, 1.5, 60.0), "reserve"), ((0.5, 0.1, -1.0), "endurance"),
                                            ((math.nan, 0.1, 60.0), "remaining")])
def test_bad_inputs(args: tuple[float, float, float], what: str) -> None:
    with pytest.raises(ValueError, match=what):
        battery_range(*args)
