"""Where a carrier braking into its stop will come to rest, so that rovers waiting above the stop
can be moved over that point while the carrier still brakes, not across once it is parked.

An ArduRover carrier starts each leg from the heading it stands at and cannot turn on the spot: it
arcs onto its line and, braking into the stop, comes to rest up to 1.3 m beside it
(docs/autopilots.md). Its telemetry shows where: the position moved on along the velocity by the
braking distance ``v² / 2a``. ``a`` is the braking the carrier shows (the speed lost between
samples at least ``SAMPLE`` mission seconds apart), never less than the carrier's stated
acceleration (an ArduRover with ``ATC_ACCEL_MAX`` 1 m/s² braked at 1.5 m/s² into its stops).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

SAMPLE = 0.2  # mission s between the speed samples the braking is read from
BRAKING_FLOOR = 0.05  # m/s lost per sample below which the carrier is not braking


@dataclass
class RestPredictor:
    """The braking and predicted rest point of one carrier (mission frame, ENU metres)."""

    accel: float  # m/s²: the carrier's stated acceleration (the least braking assumed)
    _sample: tuple[float, float] | None = None  # (mission clock, speed) of the last sample
    braking: float = 0.0  # m/s² shown over the last sample (0: not braking)

    def observe(self, now: float, speed: float | None) -> None:
        """Take the carrier's ground ``speed`` at mission clock ``now`` (once ``SAMPLE`` has passed
        since the last sample; a later call in the same sample is ignored)."""
        if speed is None or not math.isfinite(speed):
            return
        if self._sample is None:
            self._sample = (now, speed)
            return
        t0, v0 = self._sample
        if now - t0 < SAMPLE:
            return
        lost = v0 - speed
        self.braking = lost / (now - t0) if lost > BRAKING_FLOOR else 0.0
        self._sample = (now, speed)

    def rest(self, position: tuple[float, float], velocity: tuple[float, float]) -> tuple[float, float]:
        """Where the carrier at ``position`` moving at ``velocity`` (east, north) comes to rest if it
        brakes at what it shows now (at least :attr:`accel`); where it is when it is not braking."""
        speed = math.hypot(*velocity)
        if speed <= 0.0 or self.braking <= 0.0:
            return position
        a = max(self.braking, self.accel)
        reach = speed / (2.0 * a)  # braking distance / speed
        return position[0] + velocity[0] * reach, position[1] + velocity[1] * reach
