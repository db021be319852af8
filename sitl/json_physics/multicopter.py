"""A quadcopter in ArduPilot's ``+`` frame (FRAME_CLASS 1, FRAME_TYPE 0) as a rigid body.

Motor ``i`` is servo channel ``i`` (SERVO1..4_FUNCTION 33..36, ArduPilot's defaults):

==== ========= ======== ==========================
 ch  position   spins    yaw torque on the body
==== ========= ======== ==========================
 1   right      CCW      + (nose right)
 2   left       CCW      +
 3   front      CW       -
 4   back       CW       -
==== ========= ======== ==========================

Thrust follows ArduPilot's own thrust curve (``MOT_THST_EXPO``, ``MOT_SPIN_MIN``/``MAX``,
``MOT_PWM_MIN``/``MAX`` at their defaults), so the firmware's linearisation inverts it exactly
and its stock hover throttle ``MOT_THST_HOVER`` 0.39 is right from the start. Motors lag with a
first-order time constant; quadratic air drag; rotational damping.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from .body import Body
from .rigid import GRAVITY, Vec, add, cross, integrate, norm, rotate, scale, unrotate

# (forward, right) unit positions and yaw sign of the four motors of the + frame, by channel
PLUS_MOTORS: tuple[tuple[float, float, float], ...] = (
    (0.0, 1.0, 1.0), (0.0, -1.0, 1.0), (1.0, 0.0, -1.0), (-1.0, 0.0, -1.0))
_D = math.sqrt(0.5)
# PX4's quadrotor X (CA_ROTOR0..3 of its SITL quads): front right and back left spin CCW
X_MOTORS_PX4: tuple[tuple[float, float, float], ...] = (
    (_D, _D, 1.0), (-_D, -_D, 1.0), (_D, -_D, -1.0), (-_D, _D, -1.0))


@dataclass(frozen=True)
class QuadParams:
    """Physical constants (SI units). The defaults are a 1.5 kg, 0.5 m quad that hovers at the
    firmware's stock ``MOT_THST_HOVER`` (0.39 of full thrust)."""

    mass: float = 1.5
    arm: float = 0.25
    inertia: Vec = (0.03, 0.03, 0.05)
    hover_thrust: float = 0.39          # fraction of full thrust that holds the weight
    yaw_moment: float = 0.05            # rotor drag torque per newton of thrust (m)
    motor_tau: float = 0.03             # motor time constant (s)
    drag: float = 0.04                  # quadratic drag (N per (m/s)^2)
    linear_drag: float = 0.0            # first-order drag (N per m/s)
    rot_damping: Vec = (0.003, 0.003, 0.02)  # N m per rad/s
    thrust_expo: float = 0.65           # MOT_THST_EXPO
    spin_min: float = 0.15              # MOT_SPIN_MIN
    spin_max: float = 0.95              # MOT_SPIN_MAX
    pwm_min: float = 1000.0             # MOT_PWM_MIN
    pwm_max: float = 2000.0             # MOT_PWM_MAX
    motors: tuple[tuple[float, float, float], ...] = PLUS_MOTORS  # (forward, right, yaw sign) by output

    @property
    def max_thrust(self) -> float:
        """One motor's full thrust (N)."""
        return self.mass * GRAVITY / (4.0 * self.hover_thrust)

    def thrust_fraction(self, pwm: float) -> float:
        """A motor's steady thrust (fraction of full) for a servo output in microseconds."""
        if pwm <= 0:
            return 0.0
        out = (pwm - self.pwm_min) / (self.pwm_max - self.pwm_min)
        t = min(1.0, max(0.0, (out - self.spin_min) / (self.spin_max - self.spin_min)))
        e = self.thrust_expo
        return (1.0 - e) * t + e * t * t

    def pwm_for(self, fraction: float) -> float:
        """The servo output that gives ``fraction`` of full thrust (inverse of thrust_fraction)."""
        e = self.thrust_expo
        t = fraction if e == 0 else (-(1 - e) + math.sqrt((1 - e) ** 2 + 4 * e * fraction)) / (2 * e)
        out = self.spin_min + t * (self.spin_max - self.spin_min)
        return self.pwm_min + out * (self.pwm_max - self.pwm_min)


@dataclass
class Multicopter:
    """A quad's rigid body and motors. :meth:`update_motors` then either :meth:`fly` (free
    flight) or a support holds the body (see :mod:`.contact`)."""

    params: QuadParams = field(default_factory=QuadParams)
    body: Body = field(default_factory=Body)
    thrusts: list[float] = field(default_factory=lambda: [0.0] * 4)

    def update_motors(self, pwm: Sequence[int], dt: float) -> None:
        """Motors driven by ArduPilot's servo outputs (microseconds, its thrust curve)."""
        self.drive([self.params.thrust_fraction(x) for x in pwm[:4]], dt)

    def drive(self, fractions: Sequence[float], dt: float) -> None:
        """Motors driven towards ``fractions`` of full thrust (0..1, one per motor)."""
        p = self.params
        alpha = min(1.0, dt / p.motor_tau)
        full = p.max_thrust
        for i in range(4):
            f = fractions[i] if i < len(fractions) else 0.0
            target = full * min(1.0, max(0.0, f if math.isfinite(f) else 0.0))
            self.thrusts[i] += (target - self.thrusts[i]) * alpha

    def total_thrust(self) -> float:
        return sum(self.thrusts)

    def lifting(self) -> bool:
        """Whether the rotors' vertical force exceeds the weight."""
        up = rotate(self.body.attitude, (0.0, 0.0, -self.total_thrust()))[2]
        return -up > self.params.mass * GRAVITY

    def fly(self, dt: float) -> None:
        """One step of free flight (semi-implicit Euler)."""
        p, b = self.params, self.body
        arm = p.arm
        tx = ty = tz = 0.0
        for (fwd, right, yaw_sign), t in zip(p.motors, self.thrusts, strict=True):
            # r x (0, 0, -t) with r = arm * (fwd, right, 0)
            tx -= arm * right * t
            ty += arm * fwd * t
            tz += yaw_sign * p.yaw_moment * t
        w = b.gyro
        ix, iy, iz = p.inertia
        dx, dy, dz = p.rot_damping
        gyroscopic = cross(w, (ix * w[0], iy * w[1], iz * w[2]))
        wdot = ((tx - dx * w[0] - gyroscopic[0]) / ix,
                (ty - dy * w[1] - gyroscopic[1]) / iy,
                (tz - dz * w[2] - gyroscopic[2]) / iz)
        b.gyro = add(w, scale(wdot, dt))
        b.attitude = integrate(b.attitude, b.gyro, dt)
        v = b.velocity
        drag = scale(v, -(p.drag * norm(v) + p.linear_drag) / p.mass)
        thrust = rotate(b.attitude, (0.0, 0.0, -self.total_thrust() / p.mass))
        accel = (thrust[0] + drag[0], thrust[1] + drag[1], thrust[2] + drag[2] + GRAVITY)
        b.velocity = add(v, scale(accel, dt))
        b.position = add(b.position, scale(b.velocity, dt))
        b.accel_body = add((0.0, 0.0, -self.total_thrust() / p.mass), unrotate(b.attitude, drag))
