"""All vehicles of one world: copters, ground vehicles and the decks that carry copters.

Each vehicle is stepped on its own firmware's clock (one servo packet, one step of
``1 / frame_rate``); a copter resting on a deck reads its carrier's latest state.

A copter rests on a support (the ground where it touched down, or a carrier's deck) until its
rotors' vertical force exceeds its weight. On a deck it rides with the carrier: its position is
the carrier's plus the offset where it landed, turned with the carrier's heading, and its
velocity, yaw and yaw rate are the carrier's. A copter coming down from above onto a carrier's
deck (within ``Deck.radius`` horizontally of the carrier) lands on the deck, else on the ground
(``z = 0``, NED).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from .body import Body
from .ground_vehicle import GroundParams, GroundVehicle
from .multicopter import Multicopter, QuadParams
from .rigid import ZERO, Vec, add, from_yaw, norm, scale, sub, yaw_of

MAX_CONTACT_ACCEL = 30.0  # m/s^2: a touch-down's velocity change is reported over several steps
DECK_CATCH = 0.3          # m: how far below the deck surface one step may end and still land on it


@dataclass(frozen=True)
class Deck:
    """A carrier's landing deck: its top ``height`` metres above the ground, usable within
    ``radius`` metres (horizontally) of the carrier's reference point."""

    height: float = 0.5
    radius: float = 1.5


@dataclass
class Support:
    """What holds a resting copter: the ground (``carrier`` None, ``offset`` the NE position) or a
    carrier's deck (``offset`` forward/right of the carrier, ``yaw`` relative to its heading)."""

    carrier: str | None
    offset: tuple[float, float]
    yaw: float


@dataclass
class Vehicle:
    """One firmware vehicle's model, start state and instance number."""

    name: str
    instance: int
    model: Multicopter | GroundVehicle
    start: Vec
    start_yaw: float
    deck: Deck | None = None
    support: Support | None = None
    start_support: Support | None = None
    time: float = 0.0

    @property
    def body(self) -> Body:
        return self.model.body


@dataclass
class World:
    vehicles: dict[str, Vehicle] = field(default_factory=dict)

    # -- building ---------------------------------------------------------------------------
    def add_copter(self, name: str, instance: int, *, north: float = 0.0, east: float = 0.0,
                   yaw: float = 0.0, on_deck_of: str | None = None,
                   params: QuadParams | None = None) -> Vehicle:
        """A quad resting on the ground at (north, east), or on a carrier's deck at that offset
        (forward, right of the carrier's reference point; the carrier must exist already)."""
        model = Multicopter(params or QuadParams())
        if on_deck_of is None:
            support = Support(None, (north, east), 0.0)
            model.body.position = (north, east, 0.0)
            model.body.attitude = from_yaw(yaw)
        else:
            carrier = self.vehicles[on_deck_of]
            if carrier.deck is None:
                raise ValueError(f"{on_deck_of} has no deck")
            support = Support(on_deck_of, (north, east), yaw)
            self._rest(model.body, support, 1.0)
        v = Vehicle(name, instance, model, model.body.position, yaw_of(model.body.attitude),
                    support=support, start_support=support)
        return self._add(v)

    def add_ground_vehicle(self, name: str, instance: int, *, north: float = 0.0, east: float = 0.0,
                           yaw: float = 0.0, deck: Deck | None = None,
                           params: GroundParams | None = None) -> Vehicle:
        model = GroundVehicle(params or GroundParams())
        model.body.position = (north, east, 0.0)
        model.body.attitude = from_yaw(yaw)
        return self._add(Vehicle(name, instance, model, model.body.position, yaw, deck=deck))

    def _add(self, v: Vehicle) -> Vehicle:
        if v.name in self.vehicles or any(o.instance == v.instance for o in self.vehicles.values()):
            raise ValueError(f"vehicle {v.name} or instance {v.instance} twice")
        self.vehicles[v.name] = v
        return v

    def reset(self, name: str) -> None:
        """Back to the start state (the firmware restarted)."""
        v = self.vehicles[name]
        kind = type(v.model)
        v.model = kind(v.model.params)  # type: ignore[arg-type]
        v.time = 0.0
        v.support = v.start_support
        b = v.model.body
        b.position, b.attitude = v.start, from_yaw(v.start_yaw)
        if v.support is not None and v.support.carrier is not None:
            self._rest(b, v.support, 1.0)

    # -- stepping ---------------------------------------------------------------------------
    def step(self, name: str, pwm: Sequence[int], dt: float) -> Body:
        """One step driven by ArduPilot's servo outputs (microseconds)."""
        v = self.vehicles[name]
        m = v.model
        if isinstance(m, GroundVehicle):
            m.step(pwm, dt)
        else:
            m.update_motors(pwm, dt)
        return self._advance(v, dt)

    def step_controls(self, name: str, controls: Sequence[float], dt: float) -> Body:
        """One step driven by normalised controls, as PX4's HIL_ACTUATOR_CONTROLS: a quad's
        motors 0..1 of full thrust; a ground vehicle's steering and throttle -1..1 on its
        ``steering_channel`` and ``throttle_channel`` (1-based)."""
        v = self.vehicles[name]
        m = v.model
        if isinstance(m, GroundVehicle):
            p = m.params

            def channel(c: int) -> float:
                x = controls[c - 1] if 0 < c <= len(controls) else 0.0
                return max(-1.0, min(1.0, x)) if math.isfinite(x) else 0.0
            m.drive(channel(p.steering_channel), channel(p.throttle_channel), dt)
        else:
            m.drive(controls, dt)
        return self._advance(v, dt)

    def _advance(self, v: Vehicle, dt: float) -> Body:
        """Move ``v`` by one step after its motors were driven: a ground vehicle has moved; a
        copter rests on its support or flies, and may touch down."""
        v.time += dt
        m = v.model
        if isinstance(m, GroundVehicle):
            return m.body
        if v.support is not None:
            if not m.lifting():
                self._rest(m.body, v.support, dt)
                return m.body
            v.support = None
            m.body.contact_dv = ZERO  # it lifts off: what is left of a touch-down's jolt is moot
        before = m.body.position[2]
        m.fly(dt)
        v.support = self._touchdown(m.body, before)
        if v.support is not None:
            self._rest(m.body, v.support, dt)
        return m.body

    def _touchdown(self, b: Body, z_before: float) -> Support | None:
        n, e, z = b.position
        for name, c in self.vehicles.items():
            if c.deck is None:
                continue
            cn, ce, cz = c.body.position
            top = cz - c.deck.height
            if math.hypot(n - cn, e - ce) <= c.deck.radius and z >= top and z_before <= top + DECK_CATCH:
                yaw = yaw_of(c.body.attitude)
                cy, sy = math.cos(yaw), math.sin(yaw)
                dn, de = n - cn, e - ce
                return Support(name, (cy * dn + sy * de, -sy * dn + cy * de), yaw_of(b.attitude) - yaw)
        if z >= 0.0:
            return Support(None, (n, e), yaw_of(b.attitude))
        return None

    def _rest(self, b: Body, s: Support, dt: float) -> None:
        """Hold ``b`` on its support: position, level attitude, velocity and yaw rate of the support."""
        if s.carrier is None:
            position: Vec = (s.offset[0], s.offset[1], 0.0)
            velocity: Vec = (0.0, 0.0, 0.0)
            yaw, yaw_rate = yaw_of(b.attitude), 0.0
        else:
            c = self.vehicles[s.carrier]
            assert c.deck is not None
            cb = c.body
            cyaw = yaw_of(cb.attitude)
            cy, sy = math.cos(cyaw), math.sin(cyaw)
            fwd, right = s.offset
            dn, de = cy * fwd - sy * right, sy * fwd + cy * right
            position = (cb.position[0] + dn, cb.position[1] + de, cb.position[2] - c.deck.height)
            yaw_rate = cb.gyro[2]
            velocity = (cb.velocity[0] - yaw_rate * de, cb.velocity[1] + yaw_rate * dn, cb.velocity[2])
            yaw = cyaw + s.yaw
        # the whole velocity change is reported, at most MAX_CONTACT_ACCEL at a time: an
        # accelerometer that missed part of a touch-down would leave the firmware's estimator
        # believing the copter still sinks (through the ground) for seconds
        dv = add(sub(velocity, b.velocity), b.contact_dv)
        accel = scale(dv, 1.0 / dt)
        size = norm(accel)
        if size > MAX_CONTACT_ACCEL:
            accel = scale(accel, MAX_CONTACT_ACCEL / size)
        b.contact_dv = sub(dv, scale(accel, dt))
        b.position, b.velocity = position, velocity
        b.attitude = from_yaw(yaw)
        b.gyro = (0.0, 0.0, yaw_rate)
        b.set_specific_force(accel)

    # -- queries ----------------------------------------------------------------------------
    def ground_speed(self, name: str) -> float:
        """How fast the ground under ``name`` moves: a ground vehicle's own speed, the speed of the
        carrier whose deck holds a copter, else 0 (m/s)."""
        v = self.vehicles[name]
        if isinstance(v.model, GroundVehicle):
            return abs(v.model.speed)
        carrier = self.on_deck(name)
        return self.ground_speed(carrier) if carrier is not None else 0.0

    def on_deck(self, name: str) -> str | None:
        """The carrier whose deck holds ``name``, or None."""
        s = self.vehicles[name].support
        return None if s is None else s.carrier
