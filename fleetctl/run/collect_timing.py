"""Timed release of a collection round: when each rover leaves, from the carrier's live ETA.

A rover that leaves as soon as the round starts and reaches its stop before the carrier hovers
there, burning battery. Instead each rover waits where it is (on the ground, or hovering at its
task when it is in the air) and is released at

    release_i = ETA_k − flight_i − RELEASE_LEAD

so that it is above stop ``k`` when the carrier gets there; ``flight_i`` is its planned flight
(the plan's rover arrival: take-off when it starts on the ground, plus travel), ``ETA_k`` is
the carrier's arrival at ``k`` predicted from live telemetry (:class:`RoundClock`): the rest of
its current leg from its position and speed (``planners.core.timing.remaining_leg_time``), then per
stop ``depart = max(arrive, latest rover there) + land_time + load_time`` and the planned legs
between stops. A late carrier moves every ETA, and the rovers not yet released follow it.

:func:`energy_shortfalls` checks a plan against the reserve before it is flown: a rover in the
air burns ``max_speed / endurance_range`` of its battery per second until it is on the deck,
waiting included (a plan's collection flights end at the approach point, where ``land_time`` starts).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from planners.core.plan import Plan
from planners.core.problem import CarrierSpec, Vec3
from planners.core.timing import carrier_leg, path_length, remaining_leg_time, turn_time

RELEASE_LEAD = 1.0  # mission s: a rover is released this much early (its commands take time)
TURN_TOLERANCE = 0.05  # rad: a carrier at rest pointing within this of its leg does not turn
SLOW = 0.5  # m/s: a carrier slower than this is starting or stopping, not cruising
# mission s of flight a collection keeps beyond its plan: the touch-down and the carrier's arrival
# are told by telemetry up to a position sample late, and a rover burns its battery meanwhile
ENERGY_SLACK = 0.2


@dataclass
class CarrierNow:
    """The carrier's live state for an ETA: ENU position, speed (m/s), math heading (rad), and
    whether it is speeding up (then it will reach its top speed; otherwise it keeps the speed it
    has, e.g. held back below its top speed)."""

    position: Vec3
    speed: float
    heading: float
    accelerating: bool = True
    age: float = 0.0  # mission s since that position was measured (it has moved on since)


@dataclass
class RoundClock:
    """Live ETAs of one collection round's stops (mission clock)."""

    plan: Plan
    carrier: CarrierSpec
    start: float  # mission clock when the route started
    next_stop: int = 0  # the stop the carrier drives to or holds at
    arrived: dict[int, float] = field(default_factory=dict)  # stop -> when the carrier got there
    ready: dict[int, float] = field(default_factory=dict)  # stop -> latest released rover's arrival

    def reached(self, k: int, when: float) -> None:
        self.arrived[k] = when
        self.next_stop = k

    def released(self, k: int) -> None:
        self.next_stop = k + 1

    def rover_ready(self, k: int, when: float) -> None:
        self.ready[k] = max(self.ready.get(k, -math.inf), when)

    def eta(self, k: int, now: float, carrier: CarrierNow | None) -> float:
        """When the carrier will be at stop ``k`` (mission clock)."""
        if k in self.arrived:
            return self.arrived[k]
        j = min(self.next_stop, k)
        t = self._arrival(j, now, carrier)
        for m in range(j, k):
            depart = max(t, self.ready.get(m, -math.inf)) + self.carrier.collect_stop_time
            t = depart + (self.plan.stops[m + 1].arrive - self.plan.stops[m].depart)
        return t

    def makespan(self, now: float, carrier: CarrierNow | None) -> float:
        """The predicted end of the round (mission clock): the last stop's departure."""
        last = len(self.plan.stops) - 1
        if last < 0:
            return now
        t = self.eta(last, now, carrier)
        return max(t, self.ready.get(last, -math.inf)) + self.carrier.collect_stop_time

    def _arrival(self, j: int, now: float, carrier: CarrierNow | None) -> float:
        if j in self.arrived:
            return self.arrived[j]
        planned = self.start + self.plan.stops[j].arrive
        if carrier is None:
            return max(planned, now)
        stop = self.plan.stops[j]
        ahead = points_ahead(carrier.position, stop.carrier_path, stop.position)
        first = ahead[0]
        rest = math.hypot(first[0] - carrier.position[0], first[1] - carrier.position[1])
        if not self.carrier.vertex_stops:  # one leg over the rest of the path
            rest += path_length(ahead)
            ahead = ahead[-1:]
        rest = max(rest - carrier.speed * carrier.age, 0.0)  # where it is by now
        motion = self.carrier.motion
        if not carrier.accelerating and carrier.speed > SLOW:  # cruising below its top speed
            motion = dataclasses.replace(motion, max_speed=min(carrier.speed, motion.max_speed))
        t = now + remaining_leg_time(rest, carrier.speed, motion)
        heading = carrier.heading
        if rest > 0.5:
            want = math.atan2(first[1] - carrier.position[1], first[0] - carrier.position[0])
            if carrier.speed < 0.1 and abs(math.remainder(want - heading, math.tau)) > TURN_TOLERANCE:
                t += turn_time(heading, want, self.carrier.turn_rate)  # at rest: turns onto its leg first
            heading = want
        # then every segment after that vertex, from rest to rest with its turn (carrier_leg)
        return t + carrier_leg(ahead, heading, self.carrier)[0]


def points_ahead(pos: Vec3, path: list[Vec3], target: Vec3) -> list[Vec3]:
    """The vertices of a stop's carrier path still ahead of a carrier at ``pos``, the stop last:
    the end of the path's segment nearest to ``pos`` onward (a straight leg: the stop). A carrier
    at a vertex is on the segment that leaves it."""
    pts = [*path, target] if path else [pos, target]
    if math.dist(pts[-1][:2], pts[-2][:2]) < 1e-9:
        pts.pop()
    if len(pts) < 2:
        return [target]
    best, at = math.inf, len(pts) - 1
    for i, (a, b) in enumerate(zip(pts, pts[1:], strict=False), start=1):
        d = _to_segment(pos, a, b)
        if d <= best + 1e-9:
            best, at = d, i
    return pts[at:]


def _to_segment(p: Vec3, a: Vec3, b: Vec3) -> float:
    """Ground distance from ``p`` to the segment a-b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = dx * dx + dy * dy
    u = 0.0 if n <= 0.0 else min(max(((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / n, 0.0), 1.0)
    return math.hypot(a[0] + u * dx - p[0], a[1] + u * dy - p[1])


def release_delay(eta: float, flight: float, now: float) -> float:
    """Mission seconds a rover still waits before it leaves (0: go now)."""
    return max(eta - flight - RELEASE_LEAD - now, 0.0)


@dataclass(frozen=True)
class Shortfall:
    """A rover the plan would bring below its reserve."""

    rover: str
    airborne: float  # s in the air until it is on the deck, waiting included
    allowed: float  # s its battery above the reserve lasts
    flight: float = 0.0  # m: the length of its planned flight


def handling_range(max_speed: float, accel: float | None, land_time: float, takeoff_time: float = 0.0,
                   on_ground: bool = False) -> float:
    """Metres of a rover's range that a collection flight spends beyond its path, all at cruise
    speed: the touch-down (``land_time``), a rest-to-rest leg's acceleration (``v²/a``) and, for a
    rover on the ground, its release lead and take-off (``takeoff_time``), and ``ENERGY_SLACK`` -
    what :func:`energy_shortfalls` counts as time in the air. The planner is given the range less
    this, so a flight it plans can be flown within the battery (waiting for the carrier aside)."""
    ramp = 0.0 if accel is None else max_speed ** 2 / accel
    start = RELEASE_LEAD + takeoff_time if on_ground else 0.0
    return max_speed * (land_time + start + ENERGY_SLACK) + ramp


def energy_shortfalls(plan: Plan, battery: Mapping[str, float], airborne: set[str],
                      carrier: CarrierSpec, max_speed: float) -> list[Shortfall]:
    """Rovers that would be below their reserve on the deck: a rover already in the air burns its
    battery from now until it is down (``max(carrier there, rover there) + land_time``), a rover
    on the ground only from its release, each ``ENERGY_SLACK`` more. ``battery[rover]`` (metres
    above the reserve at cruise speed, from its live reading) / ``max_speed`` is the time it has."""
    out = []
    for stop in plan.stops:
        for leg in stop.rovers:
            if leg.rover not in battery:
                continue
            down = max(stop.arrive, leg.arrive) + carrier.land_time
            air = down if leg.rover in airborne else leg.arrive + RELEASE_LEAD + carrier.land_time
            air += ENERGY_SLACK
            allowed = battery[leg.rover] / max_speed
            if air > allowed + 1e-6:
                out.append(Shortfall(leg.rover, air, allowed, path_length(leg.path)))
    return out


__all__ = ["ENERGY_SLACK", "RELEASE_LEAD", "CarrierNow", "RoundClock", "Shortfall", "energy_shortfalls",
           "handling_range", "points_ahead", "release_delay"]
