"""The deck check (``fleetctl.run.state.on_deck``) against drifting altitudes."""

from __future__ import annotations

from fleetctl.run.state import DECK_RADIUS, on_deck

CARRIER = (-1.9, 1.5, -2.2)  # a ground carrier whose altitude reads 2.2 m low (PX4 SITL's rover, a minute in)


def test_a_landed_rover_next_to_a_carrier_whose_altitude_drifted_is_on_the_deck() -> None:
    assert on_deck((-1.8, 1.1, 0.0), CARRIER, on_ground=True)
    assert on_deck((-1.8, 1.1, -0.6), CARRIER, on_ground=True, speed=0.0)


def test_off_the_deck_horizontally_or_in_the_air() -> None:
    assert not on_deck((CARRIER[0] + DECK_RADIUS + 0.2, 1.5, 0.0), CARRIER, on_ground=True)
    assert not on_deck((-1.8, 1.1, 0.0), CARRIER, on_ground=False, speed=0.0)  # hovering 2.2 m up
    assert not on_deck((-1.8, 1.1, 3.0), CARRIER, on_ground=True)  # far above: a stale landed state
