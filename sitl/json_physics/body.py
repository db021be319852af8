"""The state of one simulated vehicle as the JSON interface reports it."""

from __future__ import annotations

from dataclasses import dataclass

from .rigid import GRAVITY, LEVEL, ZERO, Quat, Vec, unrotate


@dataclass
class Body:
    """Position and velocity NED in metres from the world origin, attitude body-to-earth, body
    rates, and the accelerometer's specific force in the body frame (``(0, 0, -g)`` at rest)."""

    position: Vec = ZERO
    velocity: Vec = ZERO
    attitude: Quat = LEVEL
    gyro: Vec = ZERO
    accel_body: Vec = (0.0, 0.0, -GRAVITY)
    # a contact's velocity change (m/s, earth frame) the accelerometer has yet to report: a
    # touch-down stops the body in one step, its reading spreads that over the following steps
    contact_dv: Vec = ZERO

    def set_specific_force(self, accel_earth: Vec) -> None:
        """The accelerometer reading for an earth-frame acceleration ``accel_earth``."""
        ax, ay, az = accel_earth
        self.accel_body = unrotate(self.attitude, (ax, ay, az - GRAVITY))
