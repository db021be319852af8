"""A car-like ground vehicle (ArduRover's default: steering servo on channel 1, throttle on
channel 3, both 1000..2000 us around 1500), after ArduPilot's own ``SIM_Rover``: the speed
relaxes towards ``throttle * max_speed`` with ``max_accel`` at a standing start, the turn rate
is that of a bicycle whose full-lock turning circle is ``turning_circle`` metres across.

As in ``SIM_Rover``, any throttle moves it, from rest too: there is no static friction for a
speed controller to overcome. (A standstill deadband once held an ArduRover carrier 17 s at a
stop: its waypoint controller advances its target only as the vehicle moves, so its speed demand
stayed near zero until the throttle's I term crept past the deadband.) Only unpowered -- the
throttle at trim -- does ``rolling`` resistance bring it to rest."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from .body import Body
from .rigid import GRAVITY, from_yaw, yaw_of


@dataclass(frozen=True)
class GroundParams:
    max_speed: float = 20.0        # m/s at full throttle (SIM_Rover's: 6 m/s at 30 %)
    max_accel: float = 10.0        # m/s^2 from standstill at full throttle
    turning_circle: float = 1.8    # m, diameter at full steering
    max_wheel_turn: float = 35.0   # degrees at full steering
    rolling: float = 0.5           # m/s^2 of rolling resistance when unpowered (it comes to rest)
    steering_channel: int = 1
    throttle_channel: int = 3


IDLE = 0.002  # |throttle| at or below this is trim (1 us of PWM): unpowered


def _servo(pwm: Sequence[int], channel: int) -> float:
    """A servo output as -1..1 around 1500 us (0 for a channel not driven)."""
    v = pwm[channel - 1]
    return 0.0 if v <= 0 else max(-1.0, min(1.0, (v - 1500) / 500.0))


@dataclass
class GroundVehicle:
    params: GroundParams = field(default_factory=GroundParams)
    body: Body = field(default_factory=Body)
    speed: float = 0.0       # forward, m/s
    yaw_rate: float = 0.0    # rad/s

    def turn_rate(self, steering: float, speed: float) -> float:
        p = self.params
        if abs(steering) < 1e-6 or abs(speed) < 1e-6:
            return 0.0
        diameter = p.turning_circle * math.sin(math.radians(p.max_wheel_turn)) / math.sin(
            math.radians(steering * p.max_wheel_turn))
        return 2.0 * speed / diameter

    def step(self, pwm: Sequence[int], dt: float) -> None:
        """One step driven by ArduPilot's servo outputs (microseconds)."""
        p = self.params
        self.drive(_servo(pwm, p.steering_channel), _servo(pwm, p.throttle_channel), dt)

    def drive(self, steering: float, throttle: float, dt: float) -> None:
        """One step with ``steering`` and ``throttle`` in -1..1."""
        p, b = self.params, self.body
        accel = p.max_accel * (throttle - self.speed / p.max_speed)
        before = self.speed
        if abs(throttle) <= IDLE and before != 0.0:
            accel -= math.copysign(p.rolling, before)
        self.speed += accel * dt
        if self.speed * before < 0.0 and abs(throttle) <= IDLE:
            self.speed, accel = 0.0, -before / dt   # friction stops it, it does not reverse it
        self.yaw_rate = self.turn_rate(steering, self.speed)
        yaw = yaw_of(b.attitude) + self.yaw_rate * dt
        b.attitude = from_yaw(yaw)
        c, s = math.cos(yaw), math.sin(yaw)
        b.velocity = (self.speed * c, self.speed * s, 0.0)
        n, e, _ = b.position
        b.position = (n + b.velocity[0] * dt, e + b.velocity[1] * dt, 0.0)
        b.gyro = (0.0, 0.0, self.yaw_rate)
        b.accel_body = (accel, self.speed * self.yaw_rate, -GRAVITY)
