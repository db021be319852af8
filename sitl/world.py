"""The simulated world: the carriers and their rovers, kinematics, battery, loading and unloading.

Pure Python, no I/O, no MAVLink: advance it with ``World.step(dt)``. ENU metres, z up, ground
at z = 0, the carrier's deck at z = 0 too. Motion model (matches the planners' time model):

* the carrier drives straight legs with a trapezoidal speed profile (``accel``; None = constant
  speed) and turns on the spot at ``turn_rate`` (None = instantly) before a leg; it stops at
  every target.
* a rover flies straight 3D lines at up to ``max_speed`` (vertical speed capped by
  ``climb_rate``) with the same speed profile, lands vertically at ``land_speed``; a waypoint
  flown through (``goto(..., through=True)``: one another waypoint follows) is passed without
  braking, as multirotor autopilots do.
* battery: a rover in the air (hovering included) uses ``dt * max_speed * drain_factor /
  endurance_range`` of its battery per step, i.e. ``endurance_range`` metres at cruise speed on a
  full battery, as a multirotor does; on the ground or the deck it uses none. An empty rover in
  the air lands where it is.
* a rover loaded on a carrier moves with it; any flight command detaches it; touching down
  within ``LOAD_RADIUS`` (horizontal) of a stopped carrier loads it on that carrier (with several
  carriers: any of them, not only the one it started on).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from enum import Enum

from .config import VehicleSpec

LOAD_RADIUS = 1.5  # m, horizontal distance to the stopped carrier at touchdown that loads a rover
_EPS = 1e-6


class Phase(Enum):
    LOADED = "loaded"  # riding on the carrier
    GROUND = "ground"  # landed somewhere else
    AIR = "air"


def _approach(speed: float, vmax: float, accel: float | None, dist: float, dt: float) -> float:
    """Speed at the end of the next step on a leg of remaining length ``dist``: accelerate up to
    ``vmax``, and brake so that the vehicle comes to rest at the end of the leg: the fastest end
    speed ``v`` from which a stop at ``accel`` still fits in what the step leaves,
    ``v²/(2·accel) + (speed + v)·dt/2 <= dist`` (a step covers the mean of its speeds:
    :func:`_travelled`). A leg so flown takes eq. 4.2's time within a step."""
    if accel is None:
        return vmax
    room = dist - speed * dt / 2.0
    ad = accel * dt
    fits = 0.0 if room <= 0.0 else (math.sqrt(ad * ad + 8.0 * accel * room) - ad) / 2.0
    return max(0.0, min(vmax, speed + ad, fits))


def _brake(speed: float, accel: float | None, dt: float) -> float:
    return 0.0 if accel is None else max(0.0, speed - accel * dt)


def _travelled(before: float, after: float, accel: float | None, dt: float) -> float:
    """Metres covered in a step whose speed goes from ``before`` to ``after`` at a constant
    acceleration: the mean of the two (the speed jumps at once when ``accel`` is None)."""
    return after * dt if accel is None else (before + after) * dt / 2.0


class Body:
    """State shared by the carrier and the rovers."""

    def __init__(self, spec: VehicleSpec, position: tuple[float, float, float]) -> None:
        self.spec = spec
        self.id = spec.id
        self._pos = [float(position[0]), float(position[1]), float(position[2])]
        self.vel = (0.0, 0.0, 0.0)  # m/s ENU
        self.speed = 0.0  # scalar speed along the current leg
        self.heading = math.radians(90.0 - spec.heading_deg)  # math radians (0 = east, CCW)
        self.target: tuple[float, float, float] | None = None
        self.cruise_speed = spec.max_speed
        self.moves = 0  # bumped whenever the position changes
        self.odometer = 0.0

    @property
    def position(self) -> tuple[float, float, float]:
        return (self._pos[0], self._pos[1], self._pos[2])

    def pos_key(self) -> object:
        """Changes whenever the reported position may have changed (for caches)."""
        return self.moves

    @property
    def arrived(self) -> bool:
        """No target left and at rest."""
        return self.target is None and self.speed == 0.0

    def set_speed(self, speed: float) -> None:
        self.cruise_speed = max(0.0, min(float(speed), self.spec.max_speed))

    def hold(self) -> None:
        self.target = None


class Carrier(Body):
    """A ground vehicle (or a large multirotor) on z = 0."""

    def __init__(self, spec: VehicleSpec) -> None:
        pos = spec.position or (0.0, 0.0, 0.0)
        super().__init__(spec, (pos[0], pos[1], 0.0))
        self.turn_rate = None if spec.frame == "multirotor" else spec.turn_rate

    @property
    def stopped(self) -> bool:
        return self.speed == 0.0

    def goto(self, x: float, y: float, z: float = 0.0, speed: float | None = None) -> bool:
        self.target = (float(x), float(y), 0.0)
        if speed is not None and speed > 0:
            self.set_speed(speed)
        return True

    def step(self, dt: float) -> None:
        accel = self.spec.accel
        if self.target is None:
            if self.speed > 0.0:
                self._advance(_brake(self.speed, accel, dt), dt, None)
            return
        tx, ty, _ = self.target
        dx, dy = tx - self._pos[0], ty - self._pos[1]
        dist = math.hypot(dx, dy)
        if dist < 1e-4:
            self._arrive()
            return
        want = math.atan2(dy, dx)
        err = (want - self.heading + math.pi) % (2 * math.pi) - math.pi
        if abs(err) > 1e-3 and self.turn_rate is not None:
            if self.speed > 0.0:  # stop before turning on the spot
                self._advance(_brake(self.speed, accel, dt), dt, None)
                return
            turn = self.turn_rate * dt
            self.heading = want if abs(err) <= turn else self.heading + math.copysign(turn, err)
            return
        self.heading = want
        speed = _approach(self.speed, self.cruise_speed, accel, dist, dt)
        self._advance(speed, dt, (dx / dist, dy / dist, dist))

    def _advance(self, speed: float, dt: float, leg: tuple[float, float, float] | None) -> None:
        travelled = _travelled(self.speed, speed, self.spec.accel, dt)
        self.speed = speed
        if speed <= 0.0:
            self.speed = 0.0
            self.vel = (0.0, 0.0, 0.0)
        if travelled <= 0.0:
            return
        if leg is None:
            ux, uy = math.cos(self.heading), math.sin(self.heading)
            step = travelled
        else:
            ux, uy, dist = leg
            step = min(dist, travelled)
        self._pos[0] += ux * step
        self._pos[1] += uy * step
        self.vel = (ux * self.speed, uy * self.speed, 0.0)
        self.odometer += step
        self.moves += 1
        if leg is not None and step >= leg[2] - _EPS:
            self._arrive()

    def _arrive(self) -> None:
        if self.target is not None:
            self._pos[0], self._pos[1] = self.target[0], self.target[1]
            self.moves += 1
        self.target = None
        self.speed = 0.0
        self.vel = (0.0, 0.0, 0.0)


class Rover(Body):
    """A small multirotor that rides on the carrier, flies and lands."""

    def __init__(self, spec: VehicleSpec, carrier: Carrier, decks: list[Carrier] | None = None) -> None:
        super().__init__(spec, spec.position or carrier.position)
        self.carrier = carrier  # the carrier it rides on (or last rode on)
        self.decks = decks if decks is not None else [carrier]  # every carrier it may land on
        if spec.position is None:
            self.phase = Phase.LOADED
        else:
            self.phase = Phase.AIR if spec.position[2] > 0 else Phase.GROUND
        self.climb_rate = spec.climb_rate or spec.max_speed
        self.land_speed = spec.land_speed or self.climb_rate
        self.battery = 1.0  # 0..1
        self.battery_pinned = False  # the battery holds its level (a scenario's state until it starts)
        self.flown = 0.0  # metres flown in total
        self.landing = False
        self.through = False  # the current target is a waypoint flown through
        self.passed = False  # the last target was flown through (the rover still moves)
        self._land_xy: tuple[float, float] | None = None
        self.drain_factor: Callable[[], float] = lambda: 1.0
        self.land_drift: Callable[[], float] = lambda: 0.0  # m east a landing begun now drifts
        self._drift_per_m = 0.0  # m east per metre descended, for the landing under way
        self.land_travel = 0.0  # s of its speed a rover sent down while moving travels on (PX4: 1.2)
        self._land_brake: float | None = None  # m/s², the braking of the landing under way
        self.events: list[str] = []  # "touchdown", "loaded", "battery_empty", "takeoff"

    # -- state -----------------------------------------------------------------------------
    @property
    def position(self) -> tuple[float, float, float]:
        if self.phase is Phase.LOADED:
            return self.carrier.position
        return (self._pos[0], self._pos[1], self._pos[2])

    def pos_key(self) -> object:
        return ("L", self.carrier.moves) if self.phase is Phase.LOADED else self.moves

    @property
    def loaded(self) -> bool:
        return self.phase is Phase.LOADED

    @property
    def on_ground(self) -> bool:
        return self.phase is not Phase.AIR

    @property
    def velocity(self) -> tuple[float, float, float]:
        return self.carrier.vel if self.phase is Phase.LOADED else self.vel

    # -- commands --------------------------------------------------------------------------
    def _lift_off(self) -> bool:
        if self.phase is Phase.AIR:
            return True
        if self.battery <= 0.0:
            return False
        if self.phase is Phase.LOADED:
            self._pos = list(self.carrier.position)
        self.phase = Phase.AIR
        self.speed = 0.0
        self.events.append("takeoff")
        return True

    def takeoff(self, alt: float) -> bool:
        """Climb vertically to height ``alt`` above the ground (detaches from the carrier)."""
        if not self._lift_off():
            return False
        x, y, _ = self.position
        self.landing = False
        self.through = False
        self.target = (x, y, max(float(alt), 0.1))
        return True

    def goto(self, x: float, y: float, z: float, speed: float | None = None, through: bool = False) -> bool:
        """Fly to (x, y, z); ``through``: a waypoint on the way, flown through without braking
        (``passed`` is set there and the rover keeps its speed for the next one)."""
        if speed is not None and speed > 0:
            self.set_speed(speed)
        if self.phase is not Phase.AIR and z <= 0.05:
            return False  # a rover does not drive on the ground
        if not self._lift_off():
            return False
        self.landing = False
        self.through, self.passed = through, False
        self.target = (float(x), float(y), max(float(z), 0.0))
        return True

    def land(self, x: float | None = None, y: float | None = None) -> None:
        """Land here, or fly to (x, y) at the current height and land there."""
        if self.phase is not Phase.AIR:
            return
        self.landing = True
        self.through = False
        self._drift_per_m = self.land_drift() / max(self._pos[2], 0.1)
        self._land_xy = None if x is None or y is None else (float(x), float(y))
        # down here while moving: it brakes over ``land_travel`` s of its speed (else at its accel)
        moving = self._land_xy is None and self.land_travel > 0.0 and self.speed > 0.0
        self._land_brake = self.speed / (2.0 * self.land_travel) if moving else None
        self.target = None if self._land_xy is None else (self._land_xy[0], self._land_xy[1], self._pos[2])

    def hold(self) -> None:
        self.target = None
        self.landing = False
        self.through = False

    # -- physics ---------------------------------------------------------------------------
    def step(self, dt: float) -> None:
        if self.phase is not Phase.AIR:
            return
        if self.landing and self.target is None and self.speed == 0.0:
            self._descend(dt)
        elif self.target is not None:
            self._fly_to(self.target, dt)
        elif self.speed > 0.0:
            accel = self._land_brake if self.landing and self._land_brake is not None else self.spec.accel
            self._coast(_brake(self.speed, accel, dt), dt, accel)
        elif self.landing:
            self._descend(dt)
        if self.spec.endurance_range is not None and self.battery > 0.0 and not self.battery_pinned:
            # a multirotor burns its battery per second in the air, hovering included:
            # ``endurance_range`` metres at cruise speed
            used = dt * self.spec.max_speed * self.drain_factor() / self.spec.endurance_range
            self.battery = max(0.0, self.battery - used)
            if self.battery <= 0.0:
                self.events.append("battery_empty")
                if self.phase is Phase.AIR and not (self.landing and self._land_xy is None):
                    self.land()
                    self.target = None  # straight down where it is

    def _fly_to(self, target: tuple[float, float, float], dt: float) -> None:
        p = self._pos
        dx, dy, dz = target[0] - p[0], target[1] - p[1], target[2] - p[2]
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        if dist < 1e-4:
            self._stop_at(target)
            return
        vmax = self.cruise_speed
        if abs(dz) > _EPS:
            vmax = min(vmax, self.climb_rate * dist / abs(dz))
        accel = self.spec.accel
        if self.through:  # no braking for a waypoint flown through
            speed = vmax if accel is None else min(vmax, self.speed + accel * dt)
        else:
            speed = _approach(self.speed, vmax, accel, dist, dt)
        step = min(dist, _travelled(self.speed, speed, accel, dt))
        ux, uy, uz = dx / dist, dy / dist, dz / dist
        p[0] += ux * step
        p[1] += uy * step
        p[2] += uz * step
        self.speed = speed
        self.vel = (ux * speed, uy * speed, uz * speed)
        if abs(ux) + abs(uy) > 1e-9:
            self.heading = math.atan2(uy, ux)
        self.flown += step
        self.moves += 1
        if step >= dist - _EPS:
            if self.through:
                self._pass(target)
            else:
                self._stop_at(target)

    def _pass(self, target: tuple[float, float, float]) -> None:
        self._pos = [target[0], target[1], target[2]]
        self.target, self.through, self.passed = None, False, True
        self.moves += 1

    def _stop_at(self, target: tuple[float, float, float]) -> None:
        self._pos = [target[0], target[1], target[2]]
        self.target = None
        self.speed = 0.0
        self.vel = (0.0, 0.0, 0.0)
        self.moves += 1
        if self.landing and target[2] <= 0.0:
            self._touchdown()

    def _coast(self, speed: float, dt: float, accel: float | None) -> None:
        """Brake along the current velocity (no target left) to ``speed`` at the end of the step,
        at ``accel``."""
        vx, vy, vz = self.vel
        norm = math.sqrt(vx * vx + vy * vy + vz * vz)
        step = _travelled(self.speed, speed, accel, dt)
        self.speed = max(speed, 0.0)
        if norm <= 0.0:
            self.speed = 0.0
            self.vel = (0.0, 0.0, 0.0)
            return
        ux, uy, uz = vx / norm, vy / norm, vz / norm
        self.vel = (ux * self.speed, uy * self.speed, uz * self.speed)
        if self.speed == 0.0:  # the direction is kept for the part of the step still moving
            self.vel = (0.0, 0.0, 0.0)
        if step > 0.0:
            self._pos[0] += ux * step
            self._pos[1] += uy * step
            self._pos[2] = max(0.0, self._pos[2] + uz * step)
            self.flown += step
            self.moves += 1

    def _descend(self, dt: float) -> None:
        z = self._pos[2]
        step = min(z, self.land_speed * dt)
        self._pos[2] = z - step
        self._pos[0] += self._drift_per_m * step
        self.vel = (0.0, 0.0, -self.land_speed)
        self.flown += step
        self.moves += 1
        if self._pos[2] <= 1e-9:
            self._touchdown()

    def _touchdown(self) -> None:
        self._pos[2] = 0.0
        self.vel = (0.0, 0.0, 0.0)
        self.speed = 0.0
        self.landing = False
        self._land_xy = None
        self.target = None
        deck = self._deck_below()
        if deck is not None:
            self.carrier = deck
            self.phase = Phase.LOADED
            self.events.append("loaded")
        else:
            self.phase = Phase.GROUND
        self.moves += 1
        self.events.append("touchdown")


    def _deck_below(self) -> Carrier | None:
        """The nearest stopped carrier within LOAD_RADIUS of the touch-down point, if any."""
        x, y = self._pos[0], self._pos[1]
        near = [(math.hypot(x - c.position[0], y - c.position[1]), k) for k, c in enumerate(self.decks)
                if c.stopped]
        d, k = min(near, default=(math.inf, -1))
        return self.decks[k] if d <= LOAD_RADIUS else None


AnyBody = Carrier | Rover  # a Body is always one of the two


class World:
    """The carriers and their rovers, advanced together in fixed steps. ``carrier`` is the first
    carrier (the only one of a one-carrier world); ``more_carriers`` the others. A rover starts on
    the deck of the carrier its spec names (``VehicleSpec.carrier``; None = the first)."""

    def __init__(self, carrier: VehicleSpec, rovers: list[VehicleSpec],
                 more_carriers: list[VehicleSpec] | None = None) -> None:
        self.time = 0.0
        self.carrier = Carrier(carrier)
        self.carriers: dict[str, Carrier] = {carrier.id: self.carrier}
        for spec in more_carriers or []:
            self.carriers[spec.id] = Carrier(spec)
        decks = list(self.carriers.values())
        self.rovers: dict[str, Rover] = {
            r.id: Rover(r, self.carriers.get(r.carrier or carrier.id, self.carrier), decks) for r in rovers
        }
        self.bodies: dict[str, AnyBody] = {**self.carriers, **self.rovers}

    def body(self, vehicle_id: str) -> AnyBody:
        return self.bodies[vehicle_id]

    def loaded_rovers(self, carrier: str | None = None) -> list[str]:
        """The rovers on a deck (``carrier``'s, or any carrier's)."""
        return [r.id for r in self.rovers.values()
                if r.loaded and (carrier is None or r.carrier.id == carrier)]

    def step(self, dt: float) -> None:
        for c in self.carriers.values():
            c.step(dt)
        for r in self.rovers.values():
            if r.phase is Phase.AIR:
                r.step(dt)
        self.time += dt
