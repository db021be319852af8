"""The deck check (``fleetctl.run.state.on_deck``) against drifting altitudes."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleetctl.mission import MissionError, load_mission
from fleetctl.run.state import DECK_RADIUS, on_deck

MISSIONS = Path(__file__).parents[2] / "missions"

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


def test_a_raised_deck_counts_a_rover_at_rest_on_it_before_its_landed_state() -> None:
    """``carrier.deck_height``: a deck 0.5 m above the carrier's reported altitude (the
    ``sitl.json_physics`` deck; ArduCopter on it read 0.32 - 0.43 m above its carrier at rest).
    A rover at rest on it is down before its autopilot says so; one still 0.3 m above it, or
    descending, or 0.5 m up over a deck at the carrier's altitude, is not."""
    carrier = (0.0, 0.0, 10.0)
    assert on_deck((0.3, 0.2, 10.42), carrier, on_ground=None, speed=0.0, deck=0.5)
    assert on_deck((0.3, 0.2, 10.32), carrier, on_ground=False, speed=0.05, deck=0.5)
    assert not on_deck((0.3, 0.2, 10.8), carrier, on_ground=None, speed=0.0, deck=0.5)
    assert not on_deck((0.3, 0.2, 10.6), carrier, on_ground=None, speed=0.5, deck=0.5)
    assert not on_deck((0.3, 0.2, 10.42), carrier, on_ground=None, speed=0.0)  # no deck height stated
    assert on_deck((0.3, 0.2, 11.2), carrier, on_ground=True, deck=0.5)  # the autopilot's word, 1 m slack


def test_the_deck_height_is_a_carrier_key_and_bounded(tmp_path: Path) -> None:
    text = (MISSIONS / "recon.yaml").read_text()
    ok = tmp_path / "ok.yaml"
    ok.write_text(text.replace("carrier:\n", "carrier:\n  deck_height: 0.5\n", 1))
    assert load_mission(ok).carrier.deck_height == 0.5
    assert load_mission(MISSIONS / "recon.yaml").carrier.deck_height == 0.0
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("carrier:\n", "carrier:\n  deck_height: 40\n", 1))
    with pytest.raises(MissionError, match="deck_height"):
        load_mission(bad)


def test_docs_state_the_deck_check() -> None:
    from fleetctl.mission import limits as L
    from fleetctl.run.state import DECK_HEIGHT

    docs = Path(__file__).parents[2] / "docs"
    text = (docs / "autopilots.md").read_text()
    assert "within 1.5 m\n(`DECK_RADIUS`)" in text and DECK_RADIUS == 1.5
    assert f"{DECK_HEIGHT:g} m\n(`DECK_HEIGHT`) above the deck" in text
    assert "`carrier.deck_height` (default 0" in text
    table = (docs / "mission-file.md").read_text()
    row = f"| `carrier.deck_height` | number | metres | `0.0` | \\|height\\| ≤ *{L.MAX_DECK_HEIGHT:g}*;"
    assert row in table
    assert f"within {DECK_HEIGHT:g} m above it (`DECK_HEIGHT`), within {DECK_RADIUS:g} m of the" in table
