"""The deck check (``fleetctl.run.state.on_deck``) against drifting altitudes."""

from __future__ import annotations

from fleetctl.run.state import DECK_RADIUS, on_deck

# a ground carrier whose altitude reads 3.3 m low (PX4 SITL's rover after two flights)
CARRIER = (-2.3, 1.9, -3.3)


def test_a_landed_rover_next_to_a_carrier_whose_altitude_drifted_is_on_the_deck() -> None:
    """At its own home's height (it booted, or was armed, on the deck), landed, beside the carrier."""
    assert on_deck((-2.5, 1.4, 0.0), CARRIER, on_ground=True, height=0.0)
    assert on_deck((-2.2, 1.2, -0.3), CARRIER, on_ground=True, speed=0.0, height=-0.3)


def test_a_climbing_rover_with_a_stale_landed_state_is_not() -> None:
    """1.6 m up over a carrier that reads its height right: the landed state (1 Hz) is stale."""
    assert not on_deck((0.2, 0.1, 1.6), (0.0, 0.0, 0.0), on_ground=True, height=1.6)
    assert not on_deck((-2.5, 1.4, 0.0), CARRIER, on_ground=True)  # its height above home unknown


def test_off_the_deck_horizontally_or_in_the_air() -> None:
    assert not on_deck((CARRIER[0] + DECK_RADIUS + 0.2, 1.9, 0.0), CARRIER, on_ground=True, height=0.0)
    assert not on_deck((-2.5, 1.4, 0.0), CARRIER, on_ground=False, speed=0.0, height=0.0)
    assert on_deck((-2.5, 1.4, -3.25), CARRIER, on_ground=None, speed=0.0)  # at rest on it
