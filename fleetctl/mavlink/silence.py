"""When a silent vehicle counts as *lost*: nothing heard of it (a HEARTBEAT or any other of its
messages) for ``links.heartbeat_timeout`` seconds of **mission time**, and for at least
:data:`LOST_WALL_FLOOR` wall seconds (never more than ``heartbeat_timeout`` itself).

Mission time is the run's clock (the simulator's time, or the vehicles' own time on SITL firmware
run faster than real time: :mod:`fleetctl.mavlink.vehicle_clock`; the wall clock when no run gives
one). The silence in mission time is the lesser of what
that clock and the wall clock times the nominal speed-up say: a simulator lagging behind its
speed-up, or catching up after a pause, does not make a vehicle lost sooner.

The floor is for a fleet running faster than real time: at speed-up 20 three mission seconds are
0.15 wall s, a gap that a lossy link or a busy controller (or a simulator that sends at most one
message of a stream per tick of its loop) leaves silent often; a second of wall time without a
single message of a vehicle is not. At speed-up 1 (a real link) the floor is never above the timeout, so a
real vehicle is lost after exactly ``heartbeat_timeout`` s. A look at the silence that comes more
than :data:`LATE_S` wall seconds after it was due (the controller's event loop was busy, and the
vehicle's messages may be waiting to be read) gives the vehicle the floor once more before it is
declared lost.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

LOST_WALL_FLOOR = 1.0  # wall s: a vehicle is lost only after at least this much silence (or the timeout)
LATE_S = 0.5  # wall s: a silence check this late ran on a busy event loop; the vehicle gets the floor again


@dataclass
class MissionClock:
    """The clock silences are measured on: ``now()`` in mission seconds, ``rate`` mission seconds
    per wall second (the vehicles' speed-up)."""

    now: Callable[[], float] = field(default=time.monotonic)
    rate: float = 1.0


def floor_wall(timeout: float) -> float:
    """The shortest wall-clock silence after which a vehicle may be lost."""
    return min(timeout, LOST_WALL_FLOOR)


def silence_left(timeout: float, wall_silence: float, mission_silence: float, rate: float) -> float:
    """Wall seconds until a vehicle silent for ``wall_silence`` wall seconds and ``mission_silence``
    mission seconds is lost at ``timeout`` mission seconds (``rate``: mission s per wall s);
    zero or less: lost now."""
    rate = max(rate, 1e-9)
    silent = min(mission_silence, wall_silence * rate)
    return max((timeout - silent) / rate, floor_wall(timeout) - wall_silence)


__all__ = ["LATE_S", "LOST_WALL_FLOOR", "MissionClock", "floor_wall", "silence_left"]
