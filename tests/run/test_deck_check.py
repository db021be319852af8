"""The deck check (``fleetctl.run.state.on_deck``) against drifting altitudes."""

from __future__ import annotations

from fleetctl.run.state import DECK_RADIUS, on_deck

# a ground carrier whose altitude reads 3.3 m low (PX4 SITL's rover after two flights)
CARRIER = (-2.3, 1.9, -3.3)


def test_a_landed_rover_next_to_a_carrier_whose_altitude_drifted_is_on_the_deck() -> None:
    assert on_deck((-2.5, 1.4, 0.0), CARRIER, on_ground=True)
    assert on_deck((-2.2, 1.2, -0.3), CARRIER, on_ground=True, speed=0.0)


def test_off_the_deck_horizontally_or_in_the_air() -> None:
    assert not on_deck((CARRIER[0] + DECK_RADIUS + 0.2, 1.9, 0.0), CARRIER, on_ground=True)
    assert not on_deck((-2.5, 1.4, 0.0), CARRIER, on_ground=False, speed=0.0)  # 3.3 m above it
    assert not on_deck((-2.5, 1.4, 0.0), CARRIER, on_ground=None, speed=0.0)  # landed state unknown
    assert on_deck((-2.5, 1.4, -3.25), CARRIER, on_ground=None, speed=0.0)  # at rest on it
