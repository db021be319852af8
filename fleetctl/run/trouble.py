"""Evidence that a flying rover will not get where it was sent (its task, its meeting point).

:class:`Trouble` is checked on every telemetry message of the rover (inside the phase's waits, so
it is seen as the message arrives, not at a polling rate). It reports the first evidence, in words
the journal uses:

* its battery empty (at most :data:`EMPTY_BATTERY_PCT`) - both phases;
* down on the ground after having flown, farther than :data:`DOWN_AWAY_M` (horizontally) from
  every place where it may land (its task; in collection the stop and the carrier) - both phases;
* (``failsafe``: collection) its autopilot in a failsafe mode (:data:`FAILSAFE_MODES`), or
  reporting a critical or emergency system state (MAV_STATE_CRITICAL / EMERGENCY: ArduPilot and
  PX4 report a failsafe, e.g. a critical battery, so).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from fleetctl.mavlink.vehicle import Vehicle
from planners.core.problem import Vec3

EMPTY_BATTERY_PCT = 1.0  # %: a rover reporting this little has no flight left
DOWN_AWAY_M = 3.0  # m (horizontal): a rover landed farther than this from where it may land is down short
HOLD_SPEED = 0.3  # m/s: slower than this counts as holding (or standing)
FAILSAFE_MODES = frozenset({"RTL", "SMART_RTL", "LAND"})


class Trouble:
    """First evidence that a flying rover will not arrive (see the module docstring).
    ``places``: where it may come down (called at each look: a carrier moves)."""

    def __init__(self, places: Callable[[], Sequence[Vec3 | None]], *, failsafe: bool = False) -> None:
        self.places = places
        self.failsafe = failsafe
        self.been_up = False
        self.why: str | None = None
        self.ordered: set[str] = set()  # modes the controller itself commanded (not a failsafe)

    def commanded(self, mode: str) -> None:
        """The controller put the rover in ``mode`` (e.g. LAND onto the carrier): not a failsafe."""
        self.ordered.add(mode)

    def seen(self, v: Vehicle) -> bool:
        if self.why is not None:
            return True
        if v.on_ground is False:
            self.been_up = True
        if v.battery_pct is not None and v.battery_pct <= EMPTY_BATTERY_PCT:
            self.why = f"battery empty ({v.battery_pct:.0f} %)"
        elif self.failsafe and v.armed and v.mode in FAILSAFE_MODES and v.mode not in self.ordered:
            self.why = f"switched to {v.mode} (failsafe)"
        elif self.failsafe and v.armed and v.critical:
            self.why = "its autopilot reports a critical state"
        else:
            p = v.enu
            if self.been_up and v.on_ground and p is not None and (v.ground_speed or 0.0) < HOLD_SPEED:
                places = [q for q in self.places() if q is not None]
                away = min((math.dist(p[:2], q[:2]) for q in places), default=math.inf)
                if away > DOWN_AWAY_M:
                    self.why = f"is down on the ground {away:.0f} m from where it was going"
        return self.why is not None


__all__ = ["DOWN_AWAY_M", "EMPTY_BATTERY_PCT", "FAILSAFE_MODES", "HOLD_SPEED", "Trouble"]
