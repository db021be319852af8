"""How a rover leaves and comes back to the deck, and what it costs in the time model
(docs/time-model.md): the take-off clearance, the approach height above a collection stop, and
the defaults of ``rovers.takeoff_time`` and ``rovers.land_time``.

The defaults are the vertical legs at the rover's climb and landing speeds plus a settle time
measured on the simulated fleet (``bench/flight.py``: mode change, the autopilot's take-off and
landing detection, the controller seeing it in telemetry). The climb is a rest-to-rest leg at the
rover's acceleration (eq. 4.2, ``T``); the landing descends at ``land_speed``:

    takeoff_time = T(TAKEOFF_HEIGHT; climb_rate, accel) + TAKEOFF_SETTLE
                   (TAKEOFF_HEIGHT / climb_rate + TAKEOFF_SETTLE when accel is None)
    land_time    = descent(deck_height) / land_speed + LAND_SETTLE
    descent      = MEET_HEIGHT - deck_height (the deck deck_height above the ground, at least 0)
"""

from __future__ import annotations

from planners.core.problem import Motion
from planners.core.timing import travel_time

GROUND_HEIGHT = 0.2  # m: a rover this low is on the ground (a collection flight from there takes off first)
TAKEOFF_HEIGHT = 1.0  # m above the deck: a launched rover climbs this high before it turns onto its line
MEET_HEIGHT = 3.0  # m above a collection stop: a returning rover waits here for the carrier, then lands
DEFAULT_ENDURANCE = 600.0  # s in the air on a full battery when the mission gives no endurance_range
TAKEOFF_SETTLE = 0.1  # s beyond the climb: take-off detection and the turn onto the line (measured)
LAND_SETTLE = 0.1  # s beyond the descent: touch-down detection, disarm, the controller seeing it (measured)


def default_takeoff_time(climb_rate: float, accel: float | None = None) -> float:
    """Seconds from a rover's start command to it being clear of the deck: its climb of
    ``TAKEOFF_HEIGHT`` from rest to rest at ``climb_rate`` and ``accel`` (None: instant), settled."""
    return travel_time(TAKEOFF_HEIGHT, Motion(climb_rate, accel)) + TAKEOFF_SETTLE


def descent(deck_height: float = 0.0) -> float:
    """Metres a rover comes down from ``MEET_HEIGHT`` above a collection stop onto a deck
    ``deck_height`` above the carrier's reported position (``carrier.deck_height``)."""
    return max(0.0, MEET_HEIGHT - deck_height)


def default_land_time(land_speed: float, deck_height: float = 0.0) -> float:
    """Seconds from a rover above its stop (with the carrier there) to it loaded on the deck."""
    return descent(deck_height) / land_speed + LAND_SETTLE


# carrier.firmware_speeds / rovers.firmware_speeds: write the mission's speeds to the autopilot's
# parameters before flying (set) or leave the autopilot's own (keep) - docs/autopilots.md
FIRMWARE_SPEEDS = ("set", "keep")

__all__ = ["DEFAULT_ENDURANCE", "FIRMWARE_SPEEDS", "GROUND_HEIGHT", "LAND_SETTLE", "MEET_HEIGHT",
           "TAKEOFF_HEIGHT", "TAKEOFF_SETTLE", "default_land_time", "default_takeoff_time", "descent"]
