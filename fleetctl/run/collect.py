"""The collection phase: plan the pick-up from live positions and batteries and fly it.

State lives on a :class:`RoverBoard`: each rover to collect is *pending* (waiting for a round),
*in a round* (flying to its meeting point), *loaded*, *lost*, *unreachable* (too little range
to reach the ground) or *failed* (a round could not bring it in). Each round plans the pending
rovers from their live positions and fresh
battery readings (:mod:`fleetctl.run.energy`), sends each above its meeting point (where it holds
in an unlimited loiter) and the carrier along its route; at a stop the stop's rovers are sent to
land on the carrier, which waits until every one is *loaded* (landed within
:data:`fleetctl.run.state.DECK_RADIUS`), then ``load_time`` from the last touch-down (a rover's
autopilot disarms it meanwhile; the carrier waits for that too), then goes on.

A rover lost on the way is removed: the others keep the meeting points they are flying to (on
the energy they have left, ch. 5.5.3) and stops left empty are dropped (:meth:`_trim`); a lost
rover that comes back is collected in a further round planned from the live state.

A rover that cannot arrive is *let go* (:meth:`CollectPhase._let_go`) on the first telemetry
message that shows it (:class:`fleetctl.run.trouble.Trouble`: battery empty, a failsafe mode or
critical state, down on the ground short of its stop): journalled (``rover_let_go``, with the
reason, its last position, battery and landed state), its stop no longer waits for it (the
carrier is released when it waited only for it) and the rest of the route is trimmed and re-timed.
It is not collected again (it is picked up by hand). Every wait is a deadline in mission time
(:meth:`fleetctl.run.context.RunContext.wait_for`).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from enum import StrEnum

from fleetctl.mavlink.compile import CompiledPlan, StopItems, item_position, with_meeting_hold
from fleetctl.mavlink.link import LinkError, MissionItem
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle
from fleetctl.mission.flight import GROUND_HEIGHT, MEET_HEIGHT
from fleetctl.mission.model import any_on_ground
from fleetctl.run.carrier import (
    RESTOPS_MAX,
    STAY_SPEED,
    climb_back,
    hovering_on_item,
    upload,
)
from fleetctl.run.carrier_rest import RestPredictor
from fleetctl.run.collect_timing import (
    CarrierNow,
    RoundClock,
    Shortfall,
    energy_shortfalls,
    handling_range,
    release_delay,
)
from fleetctl.run.context import RunContext
from fleetctl.run.energy import range_from_percent
from fleetctl.run.events import announce_warning, drain, race
from fleetctl.run.kinds import Ev, Phase, VehicleStatus, Watch
from fleetctl.run.launch import flight_path, rover_on_deck
from fleetctl.run.parts import PhaseParts
from fleetctl.run.results import PhaseResult
from fleetctl.run.safety import line_clear
from fleetctl.run.state import DECK_RADIUS
from fleetctl.run.supervisor import SupervisorEvent
from fleetctl.run.trouble import Trouble
from planners.core.plan import Plan, Stop
from planners.core.problem import CollectProblem, CollectRover, Vec3

log = logging.getLogger(__name__)
Point = tuple[float, float]  # east, north (mission frame)

RETARGET_OFFSET = 1.25  # m: a rover hovering this far off the carrier (the deck radius less a margin) is
# moved over it first
RETARGET_DONE = 0.5  # m: a re-targeted rover this near over the carrier, and slowed down to
RETARGET_SPEED = 1.0  # m/s (horizontally) at most, is sent down; so is one at rest (STAY_SPEED) within
RETARGET_NEAR = 1.0  # m of it (PX4 stops 0.7 - 0.8 m short of a DO_REPOSITION's point), well on the deck
RETARGET_SLACK = 5.0  # mission s on top of the flight over to the carrier
# a carrier braking to rest within FOLLOW_RANGE of its stop (or, the stop reached, parked or creeping
# at most FOLLOW_SPEED) more than FOLLOW_STEP off the point a rover near the stop flies to or holds
# over: the rover is sent there while the carrier brakes, not across once it is parked (an ArduRover
# carrier comes to rest up to 1.3 m beside its stop after a sharp turn: docs/autopilots.md)
FOLLOW_RANGE = 2.0  # m
FOLLOW_SPEED = 1.0  # m/s
FOLLOW_STEP = 0.5  # m
FOLLOW_NEAR = 6.0  # m: rovers this near their stop (horizontally) follow; farther out, only a parked
# carrier more than RETARGET_OFFSET off the stop has them sent over it
RELANDS_MAX = 1  # times a rover that touched down beside the deck takes off to land on it again
LIFT_SLACK = 0.5  # m below MEET_HEIGHT that counts as up again
DISARM_WAIT = 4.0  # mission s a rover down on the deck is given to disarm itself before it is told to
# a rover slower than this vertically, and horizontally by its velocity estimate or by its positions
# over REST_WINDOW s of its own clock, is at rest (_at_rest)
REST_SPEED = 0.2  # m/s
REST_WINDOW = 1.0  # s
LANDING_TIMEOUT = 10.0  # mission s from the land command to the rover on the deck (at least 3x land_time)
MAX_POSITION_AGE = 5.0  # mission s: an older carrier position is not moved on by its speed
SPEED_SAMPLE = 0.5  # mission s between carrier speed samples (is it speeding up?)
RECHECK = 1.0  # mission s between looks at the carrier's ETA while a rover waits for its release
# mission s: a rover waiting on the ground is armed this long (at most; RECHECK less at least) before
# its release; well within the autopilots' disarming of an idle armed vehicle (10 s)
ARM_LEAD = 2.5
ENERGY_REPLANS = 3  # plans tried with shrunk ranges before a rover short of energy is left out
SHRINK_MARGIN = 0.1  # m: a range cut for energy goes this much further
GROUND_SNAP = 1.0  # m: a landed rover reporting less than this is on the ground (altitude estimates drift)
WATCH_FOREVER = 1e9  # s: a round's trouble watch ends with the round (cancelled), not by a timeout
MIN_RANGE = 0.01  # m: what is left to plan with of a range the handling eats up (then it is short)



def landing_point(v: Vehicle) -> tuple[float, float] | None:
    """Where ``v`` comes down (east, north) if it is sent down now: its position moved on by its
    horizontal velocity times its autopilot's ``land_travel`` (PX4's quadcopter sent down at 1.1 m/s
    touched down 1.3 m on)."""
    if v.enu is None:
        return None
    travel = v.autopilot.land_travel if v.autopilot is not None else 0.0
    ve, vn = (v.velocity[0], v.velocity[1]) if v.velocity is not None else (0.0, 0.0)
    return v.enu[0] + ve * travel, v.enu[1] + vn * travel


def _landing_off(v: Vehicle, carrier: Vehicle) -> float | None:
    """How far (horizontally) from ``carrier`` ``v`` comes down if it is sent down now
    (:func:`landing_point`)."""
    p = landing_point(v)
    if p is None or carrier.enu is None:
        return None
    return math.hypot(p[0] - carrier.enu[0], p[1] - carrier.enu[1])


def _at_rest(v: Vehicle) -> bool:
    """``v`` is at rest: slower than ``REST_SPEED`` vertically by its velocity estimate, and
    horizontally by that or by its positions over the last ``REST_WINDOW`` s of its own clock
    (:meth:`Vehicle.slower_than`: PX4 SIH's estimate read 0.3 - 0.4 m/s for seconds on a rover
    standing on the ground, its positions moving 0.1 m/s)."""
    if v.velocity is None or abs(v.velocity[2]) >= REST_SPEED:
        return False
    return v.slower_than(REST_SPEED, REST_WINDOW)


async def _disarm(ctx: RunContext, v: Vehicle) -> bool:
    """Tell ``v`` to disarm: True once its ACK confirms it, False if it refuses."""
    try:
        await ctx.command(v, "disarm", v.disarm())
    except CommandRejected:
        return False
    return True


def _over(v: Vehicle, carrier: Vehicle, within: float) -> bool:
    """``v`` comes down within ``within`` m (horizontally) of ``carrier`` if it is sent down now."""
    off = _landing_off(v, carrier)
    return off is not None and off <= within


def _beside_deck(v: Vehicle, carrier: Vehicle) -> float | None:
    """How far ``v`` stands from ``carrier`` when it reports itself landed and at rest beyond the
    deck (:data:`DECK_RADIUS`), None otherwise: it touched down beside the deck."""
    if v.on_ground is not True or v.enu is None or carrier.enu is None:
        return None
    if (v.ground_speed or 0.0) > STAY_SPEED:
        return None
    off = math.hypot(v.enu[0] - carrier.enu[0], v.enu[1] - carrier.enu[1])
    return off if off > DECK_RADIUS else None


def _over_carrier(v: Vehicle, carrier: Vehicle) -> bool:
    """A rover sent over ``carrier`` may go down: within ``RETARGET_DONE`` at ``RETARGET_SPEED`` at
    most, or at rest within ``RETARGET_NEAR``."""
    speed = v.ground_speed or 0.0
    return ((_over(v, carrier, RETARGET_DONE) and speed <= RETARGET_SPEED)
            or (_over(v, carrier, RETARGET_NEAR) and speed <= STAY_SPEED))


def _surface_height(v: Vehicle, z: float) -> float:
    """The height a rover's collection flight starts from: 0 (the ground: it takes off first) for a
    rover that reports being on the ground less than ``GROUND_SNAP`` up - its altitude estimate
    (barometer, GPS) is that far off on the ground; else its height."""
    if v.on_ground is True and z < GROUND_SNAP:
        return 0.0
    return max(z, 0.0)

class RoverStatus(StrEnum):
    PENDING = "pending"
    IN_ROUND = "in_round"
    LOADED = "loaded"
    LOST = "lost"
    UNREACHABLE = "unreachable"
    FAILED = "failed"  # a round could not bring it in (upload, arm or landing failed)
    LET_GO = "let_go"  # it cannot arrive (battery empty, failsafe, down short of its stop): left where it is


@dataclass
class RoverBoard:
    """Where every rover to collect stands (see the module docstring)."""

    status: dict[str, RoverStatus] = field(default_factory=dict)  # in the order given
    loaded_at: dict[str, float] = field(default_factory=dict)  # mission s since the phase started
    lost_at_start: list[str] = field(default_factory=list)  # never heard or without a position
    why: dict[str, str] = field(default_factory=dict)  # let go / failed -> the reason

    def with_status(self, s: RoverStatus) -> list[str]:
        return [r for r, x in self.status.items() if x == s]

    def set(self, rid: str, s: RoverStatus) -> None:
        self.status[rid] = s

    def load(self, rid: str, flown: float) -> None:
        self.status[rid] = RoverStatus.LOADED
        self.loaded_at[rid] = flown

    def in_round(self, rid: str) -> bool:
        return self.status.get(rid) == RoverStatus.IN_ROUND


@dataclass
class _Round:
    """One round's mission bookkeeping: per rover, the hold and land items, and who failed."""

    plan: Plan
    compiled: CompiledPlan
    hold_seq: dict[str, int] = field(default_factory=dict)
    land_seq: dict[str, int] = field(default_factory=dict)
    items: dict[str, list[MissionItem]] = field(default_factory=dict)
    failed: set[str] = field(default_factory=set)
    start: float = 0.0  # mission clock when the route (or its trimmed rest) started
    clock: RoundClock | None = None  # live ETAs of the stops (timed release)
    going: dict[str, asyncio.Task[None]] = field(default_factory=dict)  # rover -> its timed release
    stop_of: dict[str, int] = field(default_factory=dict)  # rover -> index of its stop in the route flown
    due: dict[str, float] = field(default_factory=dict)  # rover -> expected above its stop (mission clock)
    trouble: dict[str, Trouble] = field(default_factory=dict)  # rover -> evidence it will not arrive
    watch: dict[str, asyncio.Task[None]] = field(default_factory=dict)  # rover -> its trouble watch
    touched: dict[str, float] = field(default_factory=dict)  # rover -> mission clock of its touch-down
    # rover -> the point it was sent over, out of its mission, where the carrier comes to rest
    moved: dict[str, Point] = field(default_factory=dict)

    @property
    def stops(self) -> list[Stop]:
        """The stops of the route flown (the live clock's plan once it has one)."""
        return self.clock.plan.stops if self.clock is not None else self.plan.stops


@dataclass(frozen=True)
class ResumedCollect:
    """What ``fleetctl resume`` knows of an interrupted collection."""

    elapsed: float  # mission seconds since the carrier first started collecting
    planned: float | None
    loaded: dict[str, float]  # rover -> loaded at (mission s of the phase)


class CollectPhase:
    """One collection (see the module docstring)."""

    def __init__(
        self,
        parts: PhaseParts,
        resumed: ResumedCollect | None = None,
    ) -> None:
        self.ctx, self.carrier = parts.ctx, parts.carrier
        self.supervisor, self.planning = parts.supervisor, parts.planning
        self.board = RoverBoard()
        self.plan: Plan | None = None
        self.t0: float | None = None  # mission clock when the carrier first started
        self.result = PhaseResult("collect")
        self.resumed = resumed
        self._rest: RestPredictor | None = None  # where the carrier brakes to (built at first use)
        self._speed_seen = (-math.inf, 0.0)  # (mission clock, carrier speed) of the last sample
        self._accelerating = True
        # the controller's own cost in mission s (its rovers in the air burn battery meanwhile)
        self._read_at: float | None = None  # mission clock when the round's batteries were read
        self._attempt_cost = 0.0  # the last plan-and-check attempt
        self._start_cost = 0.0  # the last round's start: from its plan checked to its route started
        self._planned_at: float | None = None  # mission clock when this round's plan passed its check

    # ============================================================================== the loop
    async def run(self, rover_ids: Iterable[str] | None = None) -> PhaseResult:
        """Collect ``rover_ids`` (default: every connected rover not on the deck)."""
        ctx = self.ctx
        ctx.state.set_phase(Phase.PLAN)
        await ctx.wait_telemetry()
        self.supervisor.start()
        self._start_board(rover_ids)
        if self.resumed is not None:
            self._adopt(self.resumed)
        last_load: float | None = None
        while True:
            drain(self.supervisor.queue, self.handle)
            batch = self.board.with_status(RoverStatus.PENDING)
            if not batch:
                ctx.replans.ready(None)
                break
            await self.carrier.ready()
            crs = await self._rover_states(batch)
            if not crs:
                continue
            await self._round(crs)
            last_load = self.result.flown if self.result.flown is not None else last_load
            self.result.flown = None
        res = self._finish(last_load)
        if res.complete and self.t0 is not None and set(res.rovers_loaded) == set(self.board.status):
            await self.carrier.park()
        return res

    def _start_board(self, rover_ids: Iterable[str] | None) -> None:
        ctx, rovers = self.ctx, self.ctx.fleet.rovers
        ids = (
            list(rover_ids)
            if rover_ids is not None
            else [rid for rid, v in rovers.items() if v.connected and not rover_on_deck(ctx, v)]
        )
        for rid in ids:
            v = rovers[rid]
            if rover_on_deck(ctx, v) and rover_ids is not None:  # already back on the carrier
                self.board.load(rid, 0.0)
                ctx.state.set_state(rid, VehicleStatus.LOADED)
            elif not v.connected or v.lost or v.enu is None:
                self.board.set(rid, RoverStatus.LOST)
                self.board.lost_at_start.append(rid)
                ctx.state.set_state(rid, VehicleStatus.LOST)
            else:
                self.board.set(rid, RoverStatus.PENDING)

    def _adopt(self, resumed: ResumedCollect) -> None:
        now = self.ctx.clock()
        self.t0 = self.result.started = now - resumed.elapsed
        self.result.planned = resumed.planned
        self.ctx.state.set_phase(Phase.COLLECT, resumed.planned, 0)
        self.ctx.state.phase_started = self.t0
        for rid, flown in resumed.loaded.items():
            self.board.load(rid, flown)
            self.ctx.state.set_state(rid, VehicleStatus.LOADED)

    async def _rover_states(self, batch: list[str]) -> list[CollectRover]:
        """Positions and ranges of ``batch`` from fresh battery readings (not the ~1 Hz stream)."""
        ctx, rp, rovers = self.ctx, self.ctx.mission.rovers, self.ctx.fleet.rovers
        await asyncio.gather(*(rovers[rid].refresh_battery() for rid in batch))
        self._read_at = ctx.clock()
        crs = []
        for rid in batch:
            v = rovers[rid]
            p = v.enu
            if p is None:
                self.board.set(rid, RoverStatus.LOST)
                continue
            rng = range_from_percent(self._battery_percent(v), rp.reserve, rp.endurance_range)
            if rng is None:
                rng = (1.0 - rp.reserve) * rp.endurance_range
                log.warning("%s reports no battery; assuming a full one", rid)
            ctx.record(Ev.ROVER_STATE, vehicle=rid, position=p, battery_pct=v.battery_pct, range=rng)
            if rng < _to_approach(p[2]):  # not even to the approach height above itself: out of reach
                self.board.set(rid, RoverStatus.UNREACHABLE)
                ctx.state.event(
                    Ev.ROVER_UNREACHABLE,
                    f"{rid}: {rng:.1f} m of range left at {p[2]:.1f} m up: cannot reach the approach "
                    f"height {MEET_HEIGHT:g} m above a stop, not collected",
                    rid,
                    range=rng,
                    height=p[2],
                )
                continue
            self.board.set(rid, RoverStatus.IN_ROUND)
            crs.append(CollectRover(rid, (p[0], p[1], _surface_height(v, p[2])), rng))
        return crs

    def _battery_percent(self, v: Vehicle) -> float | None:
        """The battery in percent, finer from the autopilot's time left in the air when it sends
        one (``time_remaining · max_speed / endurance_range``; the percentage is whole numbers)."""
        rp = self.ctx.mission.rovers
        if v.battery_time is not None and rp.endurance_range > 0:
            fine = 100.0 * v.battery_time * rp.max_speed / rp.endurance_range
            if v.battery_pct is None or abs(fine - v.battery_pct) <= 1.5:  # the same battery, finer
                return fine
        return v.battery_pct

    async def _round(self, crs: list[CollectRover]) -> None:
        ctx, st = self.ctx, self.ctx.state
        start, heading = self.carrier.pose()
        plan = await self._plan_within_reserve(crs, start, heading)
        if not plan.stops:  # every rover of the round is short of energy
            return
        compiled = self.planning.compile(plan)
        ctx.replans.ready(plan)
        if self.t0 is None:
            self.result.plan, self.result.planned = plan, plan.makespan
            st.set_phase(Phase.COLLECT, plan.makespan, len(plan.stops))
        else:
            st.planned = (ctx.clock() - self.t0) + plan.makespan
            st.stop_count, st.stop_index = len(plan.stops), 0
        self.plan = plan
        planned = {leg.rover for leg in plan.legs()}
        for c in crs:  # a rover the plan leaves out waits for the next round (not one short of energy)
            if c.id not in planned and self.board.in_round(c.id):
                self.board.set(c.id, RoverStatus.PENDING)
        await self._fly(_Round(plan, compiled))
        for rid in self.board.with_status(RoverStatus.IN_ROUND):  # not loaded in its round
            self.board.set(rid, RoverStatus.FAILED)

    async def _plan_within_reserve(self, crs: list[CollectRover], start: Vec3, heading: float) -> Plan:
        """A plan that brings no rover below its reserve: a rover in the air burns its battery while
        it waits (hovering costs as flying does); one the plan would bring too low gets a shorter
        range and the round is planned again; after ENERGY_REPLANS it is left out (unreachable).

        The controller budgets for itself: a rover in the air also burns its battery while the
        controller plans and checks, so each plan is made and checked with the battery it will
        have when the round starts - its reading less the mission time since it was read
        (:attr:`_read_at`), less what is still to come before the round flies: this attempt's own
        planning (predicted as the last attempt's measured cost) and the round's start (uploads,
        measured on the last round). Each attempt's cost is journalled (``plan_budget``)."""
        m, ctx = self.ctx.mission, self.ctx
        airborne = {c.id for c in crs if c.position[2] > GROUND_HEIGHT}
        battery = {c.id: c.range for c in crs}
        r = m.rovers
        speed = r.max_speed
        spent = {c.id: handling_range(r.max_speed, r.accel, r.land_time, r.takeoff_time, c.id not in airborne)
                 for c in crs}  # the planner plans path lengths: the rest of a flight's energy is not in them
        crs = [dataclasses.replace(c, range=max(c.range - spent[c.id], MIN_RANGE)) for c in crs]
        read_at = self._read_at if self._read_at is not None else ctx.clock()
        for attempt in range(ENERGY_REPLANS + len(crs) + 1):
            began = ctx.clock()
            # mission s the airborne rovers will have burnt when the round starts, as foreseen now
            ahead = began - read_at + self._attempt_cost + self._start_cost
            planned = [self._burnt(c, airborne, ahead) for c in crs]
            for c in planned:  # too little range for any plan: let it go, collect the others
                self._let_go_if_hopeless(c, c.id in airborne, ahead, battery[c.id] / speed)
            planned = [c for c in planned if self.board.in_round(c.id)]
            crs = [c for c in crs if self.board.in_round(c.id)]
            if not crs:
                break
            problem = CollectProblem(m.carrier_spec(), m.rovers.motion(any_on_ground(crs)), start, heading,
                                     tuple(planned), approach_height=MEET_HEIGHT, **m.environment())
            plan = await self.planning.plan("collect", problem)
            lag = ctx.clock() - read_at + self._start_cost  # measured up to now, the start foreseen
            now_battery = {rid: b - lag * speed if rid in airborne else b for rid, b in battery.items()}
            short = {s.rover: s
                     for s in energy_shortfalls(plan, now_battery, airborne, problem.carrier, speed)}
            self._attempt_cost = cost = ctx.clock() - began
            ctx.record(Ev.PLAN_BUDGET, attempt=attempt, cost=cost, since_read=ctx.clock() - read_at,
                       ahead=ahead, start_cost=self._start_cost, speedup=ctx.speedup,
                       airborne=sorted(airborne), short=sorted(short))
            if not short:
                self._planned_at = ctx.clock()
                return plan
            # the shrunk ranges are the ranges at the round's start as seen now: back to the reading
            back = {c.id: c for c in self._shrink(planned, short, hopeless=attempt >= ENERGY_REPLANS)}
            crs = [c if c.id not in short else dataclasses.replace(
                       back[c.id], range=back[c.id].range + (lag * speed if c.id in airborne else 0.0))
                   for c in crs if c.id in back]
            if not crs:
                break
            ctx.record(Ev.ROVER_STATE, text="replanned: rovers short of energy", rovers=sorted(short))
        return Plan("collect", "none", start, heading, [])  # nobody left to collect this round

    def _let_go_if_hopeless(self, c: CollectRover, up: bool, ahead: float, allowed: float) -> None:
        """Leave ``c`` out when its planned range cannot even take it to the approach height above a
        stop (nor, in the air, down from where it hovers): the controller's own time (``ahead`` mission
        s) or a landed rover's take-off and landing leave it too little, and no plan could hold it."""
        z = c.position[2]
        need = max(z, _to_approach(z)) if up else _to_approach(z)
        if c.range >= need:
            return
        why = (f"{c.id}: {c.range:.1f} m of range left once the round starts ({ahead:.1f} s of the "
               f"controller's own time from now), too little to come down from {z:.1f} m: not collected"
               if up else
               f"{c.id}: {c.range:.1f} m of range left after its take-off and landing, less than the "
               f"{need:.1f} m climb to the approach height above a stop: not collected")
        self._short_of_energy(c.id, ahead, allowed, why=why)

    def _burnt(self, c: CollectRover, airborne: set[str], seconds: float) -> CollectRover:
        """``c`` with the range an airborne rover burns in ``seconds`` of mission time taken off."""
        if c.id not in airborne or seconds <= 0.0:
            return c
        burnt = seconds * self.ctx.mission.rovers.max_speed
        return dataclasses.replace(c, range=max(c.range - burnt, MIN_RANGE))

    def _shrink(
        self, crs: list[CollectRover], short: dict[str, Shortfall], hopeless: bool
    ) -> list[CollectRover]:
        """The rovers to plan again: one short of energy with its range cut by the excess, or left
        out (unreachable) once that leaves it nothing or the replans are used up (``hopeless``:
        every later plan leaves out at least one more rover, so this ends)."""
        speed, keep = self.ctx.mission.rovers.max_speed, []
        for c in crs:
            s = short.get(c.id)
            if s is None:
                keep.append(c)
                continue
            # below what it flies now (its range may be longer than its flight), by the excess
            shrunk = min(c.range, s.flight) - (s.airborne - s.allowed) * speed - SHRINK_MARGIN
            if hopeless or shrunk <= _to_approach(c.position[2]):
                self._short_of_energy(c.id, s.airborne, s.allowed)
            else:
                keep.append(dataclasses.replace(c, range=shrunk))
        return keep

    def _short_of_energy(self, rid: str, airborne: float, allowed: float, why: str | None = None) -> None:
        """Leave ``rid`` out (``why``: the words, default: its flight against what it has left); in
        the air it lands where it is while it still has its reserve (rather than hover its battery
        away), to be picked up by hand."""
        v = self.ctx.fleet.rovers[rid]
        up = v.on_ground is False or (v.height or 0.0) > GROUND_HEIGHT
        self.board.set(rid, RoverStatus.UNREACHABLE)
        text = why or (f"{rid}: would be {airborne:.0f} s in the air before it is on the deck but has "
                       f"{allowed:.0f} s above its reserve: not collected")
        self.ctx.state.event(
            Ev.ROVER_UNREACHABLE,
            text + ("; landing where it is" if up else ""),
            rid, airborne=airborne, allowed=allowed,
        )
        if up:
            self.ctx.spawn(self._land_in_place(v), f"land {rid}")

    async def _land_in_place(self, v: Vehicle) -> None:
        try:
            await self.ctx.command(v, "land", v.land())
        except (CommandRejected, LinkError, TimeoutError) as exc:
            log.warning("%s: could not land: %s", v.name, exc)

    # ============================================================================== one round
    async def _fly(self, rnd: _Round) -> None:
        await self._send_rovers(rnd)
        ctx = self.ctx
        q = self.supervisor.queue
        stops, cstops = list(rnd.plan.stops), list(rnd.compiled.stops)
        rnd.start = ctx.state.plan_started = ctx.clock()
        k, prev = 0, 0.0
        while k < len(stops):
            stop, items = stops[k], cstops[k]
            follows = [asyncio.create_task(self._follow_in(rnd, leg.rover, k, items.arrive_seq, False))
                       for leg in stop.rovers]
            try:
                ok, _ = await race(
                    q, self.carrier.reach_stop(k, items.arrive_seq, stop.arrive - prev), self.handle
                )
            finally:
                for t in follows:
                    t.cancel()
                await asyncio.gather(*follows, return_exceptions=True)
            if not ok:
                stops, cstops = await self._trim(rnd, stops[k:], cstops[k:])
                k, prev = 0, 0.0
                continue
            prev = stop.depart
            self._at_stop(rnd, k)
            await self._bring_all_in(rnd, stop, k, items.arrive_seq)
            await ctx.sleep_mission(self._load_left(rnd, [leg.rover for leg in stop.rovers]))
            assert self.t0 is not None
            self.result.flown = ctx.clock() - self.t0
            if drain(q, self.handle) and k + 1 < len(stops):
                rest_items = cstops[k + 1 :]
                stops, cstops = await self._trim(rnd, stops[k + 1 :], rest_items)
                if cstops == rest_items and cstops:  # the same route goes on: let the carrier go
                    await self.carrier.release(k, items.release_seq)
                k, prev = 0, 0.0
                continue
            await self.carrier.release(k, items.release_seq)
            if rnd.clock is not None:
                rnd.clock.released(k)
            k += 1
        for t in (*rnd.going.values(), *rnd.watch.values()):
            t.cancel()

    async def _bring_all_in(self, rnd: _Round, stop: Stop, k: int, seq: int) -> None:
        """Bring the rovers of stop ``k`` in (:meth:`_bring_in`). A carrier that does not stand still
        on its own (:attr:`CarrierControl.stands_disarmed`) is held on the stop meanwhile, as soon
        as it stands (:meth:`CarrierControl.hold_once_holdable`): it settles while they come in."""
        holding = None
        if self.carrier.stands_disarmed:
            holding = asyncio.create_task(self.carrier.hold_once_holdable(k, seq))
        try:
            await asyncio.gather(*(self._bring_in(rnd, leg.rover, leg.arrive, k, seq) for leg in stop.rovers))
        finally:
            if holding is not None:
                holding.cancel()
                await asyncio.gather(holding, return_exceptions=True)

    async def _send_rovers(self, rnd: _Round) -> None:
        """Upload every rover's way back (with a hold above its meeting point), start the
        carrier, then the rovers."""
        ctx, st, rovers = self.ctx, self.ctx.state, self.ctx.fleet.rovers
        for rid, rm in rnd.compiled.rovers.items():
            items, rnd.hold_seq[rid], rnd.land_seq[rid] = with_meeting_hold(rm, rovers[rid].autopilot)
            rnd.items[rid] = items
        results = await asyncio.gather(
            *(upload(ctx, rovers[rid], items) for rid, items in rnd.items.items()), return_exceptions=True
        )
        for rid, r in zip(rnd.items, results, strict=True):
            if isinstance(r, BaseException):
                rnd.failed.add(rid)
                st.event(Ev.ROVER_FAILED, f"{rid}: mission upload failed ({r})", rid)
        await self.carrier.start_route(rnd.compiled)
        rnd.start = ctx.clock()
        if self._planned_at is not None:
            self._start_cost = rnd.start - self._planned_at
        if self.t0 is None:
            self.t0 = self.result.started = st.phase_started = rnd.start
        rnd.clock = RoundClock(rnd.plan, ctx.mission.carrier_spec(), rnd.start)
        for k, stop in enumerate(rnd.plan.stops):
            for leg in stop.rovers:
                if leg.rover in rnd.items and leg.rover not in rnd.failed:
                    rnd.stop_of[leg.rover] = k
                    rnd.trouble[leg.rover] = Trouble(self._landing_places(rnd, leg.rover), failsafe=True)
                    go = self._go(rnd, leg.rover, leg.arrive)
                    rnd.going[leg.rover] = ctx.spawn(go, f"release {leg.rover}")
                    rnd.watch[leg.rover] = ctx.spawn(self._watch(rnd, leg.rover), f"watch {leg.rover}")
        for rid in rnd.failed:
            if self.board.in_round(rid):
                self.board.set(rid, RoverStatus.LOST if rovers[rid].lost else RoverStatus.FAILED)
        st.event(Ev.COLLECTION_STARTED, f"collecting {len(rnd.items) - len(rnd.failed)} rovers", None,
                 at=rnd.start)

    def _retime_round(self, rnd: _Round, rest: Plan) -> None:
        """The route goes on as ``rest`` (a trimmed one): the live ETAs and each waiting rover's
        stop follow it."""
        rnd.clock = RoundClock(rest, self.ctx.mission.carrier_spec(), self.ctx.clock())
        rnd.stop_of = {leg.rover: k for k, stop in enumerate(rest.stops) for leg in stop.rovers}

    def _carrier_now(self) -> CarrierNow | None:
        c = self.ctx.fleet.carrier
        if c.enu is None:
            return None
        pos, heading = self.carrier.pose()
        speed, now = c.ground_speed or 0.0, self.ctx.clock()
        t0, v0 = self._speed_seen
        if now - t0 >= SPEED_SAMPLE:
            self._speed_seen, self._accelerating = (now, speed), speed > v0 + 0.1
        age = (c.position_age or 0.0) * self.ctx.speedup
        return CarrierNow(pos, speed, heading, self._accelerating, min(age, MAX_POSITION_AGE))

    def _at_stop(self, rnd: _Round, k: int) -> None:
        """The carrier is at stop ``k``: fix its arrival in the round's clock, predict the end."""
        now = self.ctx.clock()
        if rnd.clock is not None:
            rnd.clock.reached(k, now)
            self._predict(rnd)
            self.ctx.record(Ev.ETA, phase="collect", stop=k + 1, eta=self.ctx.state.eta)

    def _predict(self, rnd: _Round) -> None:
        if rnd.clock is not None and self.t0 is not None:
            self.ctx.state.eta = rnd.clock.makespan(self.ctx.clock(), self._carrier_now()) - self.t0

    async def _go(self, rnd: _Round, rid: str, flight: float) -> None:
        """Release ``rid`` when it is due (timed release: above stop ``k`` as the carrier gets
        there), then arm it and start its way back."""
        ctx, v = self.ctx, self.ctx.fleet.rovers[rid]
        assert rnd.clock is not None
        while not v.lost:
            if not self.board.in_round(rid):  # let go while it waited
                return
            now = ctx.clock()
            k = rnd.stop_of[rid]  # (a trimmed route renumbers the stops)
            wait = release_delay(rnd.clock.eta(k, now, self._carrier_now()), flight, now)
            self._predict(rnd)
            if wait <= 0.0:
                break
            if wait <= ARM_LEAD and not v.armed and v.on_ground:
                await self._arm_ahead(v)
            ctx.state.set_state(rid, VehicleStatus.WAITING)
            await ctx.sleep_mission(min(wait, RECHECK))
        try:
            if not v.armed:
                await ctx.command(v, "arm", v.arm())
            await ctx.command(v, "start_mission", v.start_mission())
            now = ctx.clock()
            rnd.due[rid] = now + flight
            rnd.clock.rover_ready(rnd.stop_of[rid], now + flight)
            ctx.state.set_state(rid, VehicleStatus.RETURNING)
            self.supervisor.expect(rid, flight_path(ctx, rnd.compiled.rovers[rid], v.enu or (0.0, 0.0, 0.0)))
        except (CommandRejected, LinkError, TimeoutError) as exc:
            ctx.state.event(Ev.ROVER_FAILED, f"{rid}: cannot start its way back ({exc})", rid)
            rnd.failed.add(rid)

    async def _arm_ahead(self, v: Vehicle) -> None:
        """Arm a rover waiting on the ground shortly before its release, so that its motors have
        spun up when it is started (as a deployment arms its rovers while the carrier unloads): on
        ArduCopter arming then starting at once takes 2 s longer to lift off. Refused: it is armed
        again at its release."""
        with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
            await self.ctx.command(v, "arm", v.arm())

    async def _bring_in(self, rnd: _Round, rid: str, leg_arrive: float, k: int, seq: int) -> None:
        """Wait for ``rid`` above stop ``k`` (the carrier's arrive item ``seq``), send it down onto
        the carrier parked there, wait until loaded."""
        ctx, st = self.ctx, self.ctx.state
        v = ctx.fleet.rovers[rid]
        going = rnd.going.get(rid)
        if going is not None and not going.done():
            await ctx.wait_task(going, ctx.late(leg_arrive + RECHECK))
        if rid in rnd.failed or not self.board.in_round(rid):
            return
        try:
            over = await self._wait_meeting_point(rnd, v, leg_arrive, k, seq)
            if v.lost or not self.board.in_round(rid):
                return
            await self._land_on_parked(rnd, v, k, seq, over_carrier=over)
            if v.lost or not self.board.in_round(rid):
                return
            rnd.touched[rid] = ctx.clock()
            await self._disarmed_on_deck(v)
        except (CommandRejected, LinkError, TimeoutError) as exc:
            self.board.why[rid] = f"not loaded ({exc})"
            st.event(Ev.ROVER_FAILED, f"{rid}: not loaded ({exc})", rid)
            return
        assert self.t0 is not None
        flown = ctx.clock() - self.t0
        self.board.load(rid, flown)
        self.supervisor.expect(rid, None)
        st.set_state(rid, VehicleStatus.LOADED)
        st.event(Ev.ROVER_LOADED, f"{rid}: loaded on the carrier at {flown:.1f} s", rid, flown=flown)

    async def _land_on_parked(self, rnd: _Round, v: Vehicle, k: int, seq: int,
                              over_carrier: bool = False) -> None:
        """Land ``v`` on the carrier once it is parked at stop ``k`` (:meth:`CarrierControl.parked`:
        the rover hovers meanwhile). A carrier that leaves the stop during the descent
        (:meth:`CarrierControl.has_left`) breaks the landing off: the rover climbs back to
        ``MEET_HEIGHT`` where it is, the carrier is sent back onto the stop and stopped there,
        disarmed (:meth:`CarrierControl.hold_on_stop`), and the rover is brought down over it again.
        A carrier that does not stand still on its own is held so at once
        (:attr:`CarrierControl.stands_disarmed`).
        ``over_carrier``: ``v`` flies out of its mission (sent over the carrier on its way)."""
        ctx, c, rid = self.ctx, self.ctx.fleet.carrier, v.name
        landing = max(LANDING_TIMEOUT, 3.0 * ctx.mission.rovers.land_time)
        if not over_carrier:
            await self._follow_in(rnd, rid, k, seq, True)
        broken_off = over_carrier or rid in rnd.moved
        relands = 0
        hold = self.carrier.stands_disarmed  # held where it parks next (or once it drove off under a landing)
        for _ in range(RESTOPS_MAX + RELANDS_MAX):
            await self.carrier.parked(k, seq, hold=hold)
            if not rover_on_deck(ctx, v):
                await self._send_down(rnd, v, over_carrier=broken_off)
                ctx.state.set_state(rid, VehicleStatus.LANDED)

            def down_or_left(v: Vehicle) -> bool:
                return (rover_on_deck(ctx, v) or self._down_on_deck(rnd, v) or v.lost or self._gone(rnd, v)
                        or (self.carrier.has_left(seq) and v.on_ground is not True)
                        or _beside_deck(v, c) is not None)

            await ctx.wait_for(v, down_or_left, landing, "landing on the carrier")
            if rover_on_deck(ctx, v) or self._down_on_deck(rnd, v) or v.lost or not self.board.in_round(rid):
                return
            off = _beside_deck(v, c)
            if off is not None:
                relands += 1
                if relands > RELANDS_MAX:
                    raise TimeoutError(f"landed {off:.1f} m off the carrier, beside its deck, "
                                       f"{relands} times")
                await self._lift_again(v, off, k)
            else:
                await climb_back(ctx, v, k + 1)
                hold = True
            broken_off = True
        raise TimeoutError(f"the carrier left stop {k + 1} {RESTOPS_MAX} times")

    async def _lift_again(self, v: Vehicle, off: float, k: int) -> None:
        """``v`` touched down ``off`` m from the carrier parked at stop ``k``, beside its deck: it takes
        off again to ``MEET_HEIGHT`` (journalled) and is then brought down over the carrier
        (:meth:`_send_down` with ``over_carrier``). Its motors are off first (:meth:`_disarmed_on_deck`),
        then it is armed and given its take-off command: a landed autopilot disarms itself on its
        own (PX4 ``COM_DISARM_LAND``), and one that does so just after the take-off command stays on
        the ground (PX4 SIH: disarmed 0.5 s after the take-off was accepted, collection incomplete)."""
        ctx, rid = self.ctx, v.name
        text = (f"{rid}: landed {off:.1f} m off the carrier at stop {k + 1}, beside its deck: "
                "taking off to land again")
        ctx.record(Ev.ROVER_STATE, vehicle=rid, text=text, offset=off)
        ctx.state.set_state(rid, VehicleStatus.WAITING)
        await self._disarmed_on_deck(v)  # its ACK, or its HEARTBEAT, shows it disarmed: armed again
        await ctx.command(v, "arm", v.arm())
        await ctx.command(v, "takeoff", v.takeoff(MEET_HEIGHT))
        climb = ctx.mission.rovers.takeoff_time + MEET_HEIGHT / ctx.mission.rovers.climb_rate
        await ctx.wait_for(v, lambda v: v.lost or (v.height or 0.0) >= MEET_HEIGHT - LIFT_SLACK,
                           climb + RETARGET_SLACK, "up again beside the deck")

    def _carrier_off_stop(self, rnd: _Round, v: Vehicle, k: int, seq: int, reached: bool = True,
                          target: Point | None = None) -> tuple[float, Point] | None:
        """Where the carrier comes to rest at stop ``k`` (its arrive item ``seq``:
        :meth:`_coming_to_rest`; ``reached``: the stop is reached) and how far that is from
        ``target`` (the planned stop by default), while ``v`` flies to or holds over it. None unless
        that is more than ``FOLLOW_STEP`` off for a rover within ``FOLLOW_NEAR`` of the stop (whose
        autopilot :attr:`~Autopilot.follows_braking_carrier`), more than ``RETARGET_OFFSET`` off a
        parked carrier for any other; ``v`` is in the air on a straight way there, and the line from
        ``v`` to it is clear (:func:`line_clear`)."""
        c = self.ctx.fleet.carrier
        stops = rnd.stops
        if (v.lost or v.on_ground is not False or (v.height or 0.0) <= GROUND_SNAP or k >= len(stops)
                or c.enu is None or v.enu is None):
            return None
        stop = stops[k]
        follows = v.autopilot is None or v.autopilot.follows_braking_carrier
        near = follows and math.hypot(v.enu[0] - stop.position[0], v.enu[1] - stop.position[1]) <= FOLLOW_NEAR
        point = self._coming_to_rest(stop, seq, reached, near)
        if point is None:
            return None
        x, y = target if target is not None else (stop.position[0], stop.position[1])
        off = math.hypot(point[0] - x, point[1] - y)
        straight = any(leg.rover == v.name and len(leg.path) <= 2 for leg in stop.rovers)
        if (off <= (FOLLOW_STEP if near else RETARGET_OFFSET) or not straight
                or not line_clear(self.ctx.mission, v.enu, (*point, 0.0))):
            return None
        return off, point

    def _coming_to_rest(self, stop: Stop, seq: int, reached: bool, near: bool) -> Point | None:
        """Where the carrier will stand at ``stop`` (its arrive item ``seq``): where it is once the
        stop is ``reached`` and it is parked there; for a rover ``near`` the stop also where it
        brakes to (:class:`RestPredictor`; after the stop is reached, where it creeps at most
        ``FOLLOW_SPEED``) when that is within ``FOLLOW_RANGE`` of the stop. None otherwise (still
        on its way, or standing where it starts from)."""
        c = self.ctx.fleet.carrier
        if c.enu is None:
            return None
        here = (c.enu[0], c.enu[1])
        if reached and self.carrier.is_parked(seq):
            return here
        if not near or c.velocity is None or c.ground_speed is None:
            return None
        if self._rest is None:
            accel = self.ctx.mission.carrier.accel
            self._rest = RestPredictor(accel if accel is not None else math.inf)
        self._rest.observe(self.ctx.clock(), c.ground_speed)
        if self._rest.braking <= 0.0 and not (reached and c.ground_speed <= FOLLOW_SPEED):
            return None
        point = self._rest.rest(here, (c.velocity[0], c.velocity[1]))
        if math.hypot(point[0] - stop.position[0], point[1] - stop.position[1]) > FOLLOW_RANGE:
            return None
        return point

    async def _follow_in(self, rnd: _Round, rid: str, k: int, seq: int, reached: bool) -> None:
        """While the carrier comes in to stop ``k`` (its arrive item ``seq``), keep ``rid``, flying to
        or holding above the stop, heading for where the carrier will stand: each time that place
        (:meth:`_carrier_off_stop`) is more than ``FOLLOW_STEP`` off the point ``rid`` flies to,
        ``rid`` is sent over it (:meth:`_meet_over_carrier`; ``rnd.moved``), so that it is above the
        carrier when the carrier parks instead of crossing over then. Until the carrier is parked,
        or was due there with the stated slack, or the task is cancelled (the stop reached)."""
        ctx, c = self.ctx, self.ctx.fleet.carrier
        v = ctx.fleet.rovers.get(rid)
        if v is None or k >= len(rnd.stops):
            return
        stop = rnd.stops[k]
        end = ctx.clock() + ctx.late(max(rnd.start + stop.arrive - ctx.clock(), 0.0))

        def target() -> Point:
            return rnd.moved.get(rid, (stop.position[0], stop.position[1]))

        def due(_c: Vehicle) -> bool:
            return (self.carrier.is_parked(seq) or v.lost or not self.board.in_round(rid)
                    or self._carrier_off_stop(rnd, v, k, seq, reached, target()) is not None)

        while True:
            try:
                await ctx.wait_for(c, due, end - ctx.clock(), "the carrier coming to its stop")
            except TimeoutError:
                return
            found = self._carrier_off_stop(rnd, v, k, seq, reached, target())
            if found is None or not self.board.in_round(rid):
                return
            if not await self._meet_over_carrier(rnd, v, found[1], k) or self.carrier.is_parked(seq):
                return  # refused: it keeps to where it flies

    async def _meet_over_carrier(self, rnd: _Round, v: Vehicle, point: Point, k: int) -> bool:
        """Send ``v``, on its way to or above stop ``k``, straight over ``point``, where the carrier
        comes to rest, at its hold's height (DO_REPOSITION), instead of to the stop and then across.
        Returns whether it was (refused: it keeps its mission)."""
        ctx, rid = self.ctx, v.name
        height = rnd.items[rid][rnd.hold_seq[rid]].z
        stop = rnd.stops[k].position
        off = math.hypot(point[0] - stop[0], point[1] - stop[1])
        text = f"{rid}: the carrier comes to rest {off:.1f} m off stop {k + 1}: flying over the carrier"
        ctx.record(Ev.ROVER_STATE, vehicle=rid, text=text, offset=off)
        before = rnd.moved.get(rid)
        rnd.moved[rid] = point  # before the command: it may fly there although its answer is lost
        try:
            await ctx.command(v, "goto", v.goto_enu(point[0], point[1], height))
        except CommandRejected:
            if before is None:
                rnd.moved.pop(rid, None)
            else:
                rnd.moved[rid] = before
            return False
        if v.enu is not None:
            self.supervisor.expect(rid, [v.enu, (point[0], point[1], v.enu[2])])
        return True

    def _at_meeting_point(self, rnd: _Round, v: Vehicle) -> bool:
        """``v`` holds above its stop: its hold is the current item, or its autopilot reported the
        approach waypoint before it, or its position shows it at rest in the air on its hold."""
        hold = rnd.hold_seq[v.name]
        return ((v.mission_current or 0) >= hold or hold - 1 in v.items_reached
                or (hovering_on_item(v, hold) and (v.height or 0.0) > GROUND_SNAP))

    async def _send_down(self, rnd: _Round, v: Vehicle, over_carrier: bool = False) -> None:
        """Land ``v`` on the carrier: its mission's landing straight below it (its landing mode
        where that item would settle first: ``Autopilot.mission_landing_settles``), or - when it would
        come down (:func:`landing_point`: where it is, or on along its way for an autopilot whose
        landing mode travels on) more than ``RETARGET_OFFSET`` off the stopped carrier (autopilots
        stop within their acceptance radius, an Ackermann carrier may overshoot its stop; one held
        disarmed on its stop is stopped), or its mission's landing item is (an
        autopilot whose mission landing flies to the item first lands there: PX4 set one down 1.6 m
        off a carrier it hovered 1.2 m off) - over the carrier's live position first
        (DO_REPOSITION), then straight down, so that a rover lands on the deck, never beside it.
        ``over_carrier``: always over the carrier first (a rover whose landing was broken off flies
        a DO_REPOSITION, out of its mission)."""
        ctx, rid = self.ctx, v.name
        c = ctx.fleet.carrier
        ap = v.autopilot
        settles = ap is not None and ap.mission_landing_settles
        off = _landing_off(v, c)
        if off is not None and not settles and c.enu is not None and c.origin is not None:
            x, y, _z = item_position(rnd.items[rid][rnd.land_seq[rid]], c.origin)
            off = max(off, math.hypot(c.enu[0] - x, c.enu[1] - y))  # where its mission would land it
        # still coming to its stop (a carrier held disarmed stands: its velocity estimate is not trusted)
        moving = not self.carrier.held_on_stop and (c.ground_speed is None or c.ground_speed > STAY_SPEED)
        if off is None or c.position is None or not (over_carrier or (off > RETARGET_OFFSET and not moving)):
            if over_carrier or settles:
                # out of its mission, the carrier's position unknown, or a mission landing that
                # would settle first: down where it hovers
                if (trouble := rnd.trouble.get(rid)) is not None:
                    trouble.commanded("LAND")
                await ctx.command(v, "land", v.land())
            else:
                await ctx.command(v, "set_current", v.set_current(rnd.land_seq[rid]), seq=rnd.land_seq[rid])
            return
        lat, lon, _alt = c.position
        height = v.height if v.height is not None else MEET_HEIGHT
        where = "" if over_carrier else " above its stop"
        text = f"{rid}: would come down {off:.1f} m off the carrier{where}: landing over the carrier"
        ctx.record(Ev.ROVER_STATE, vehicle=rid, text=text, offset=off)
        try:
            await ctx.command(v, "goto", v.goto(lat, lon, height))
        except CommandRejected:  # it cannot be moved: its mission's landing on the planned stop
            await ctx.command(v, "set_current", v.set_current(rnd.land_seq[rid]), seq=rnd.land_seq[rid])
            return
        speed = ctx.mission.rovers.max_speed
        with contextlib.suppress(TimeoutError):  # not quite over it in time: down from where it is
            await ctx.wait_for(v, lambda v: v.lost or _over_carrier(v, c),
                               off / speed + RETARGET_SLACK, "over the carrier")
        trouble = rnd.trouble.get(rid)
        if trouble is not None:
            trouble.commanded("LAND")
        await ctx.command(v, "land", v.land())

    def _load_left(self, rnd: _Round, rovers: list[str]) -> float:
        """Mission seconds of ``load_time`` still to wait at a stop: the loading of a rover starts at
        its touch-down (its autopilot disarms it meanwhile), so it ends ``load_time`` after the
        last touch-down of the stop's rovers."""
        load = self.ctx.mission.carrier.load_time
        down = [rnd.touched[r] for r in rovers if r in rnd.touched]
        if not down:
            return load
        return max(0.0, load - (self.ctx.clock() - max(down)))

    async def _disarmed_on_deck(self, v: Vehicle) -> None:
        """A rover down on the deck counts as loaded once its motors are off, so the carrier never
        drives off with a rover armed on it (whose land detector a moving deck may keep from
        finishing): its autopilot disarms it on its own after the landing (ArduCopter about 2 s
        after the touch-down; PX4 ``COM_DISARM_LAND`` after its land detector, so a PX4 rover is told
        to as soon as it reports itself landed, or is at rest on the deck (:func:`_at_rest`: PX4 SIH's
        land detector missed landings for seconds - in one collection for 34 s - while the rover stood
        on the ground beside the carrier): ``Autopilot.disarm_when_landed``); after
        ``DISARM_WAIT`` mission seconds without a HEARTBEAT showing it disarmed, it is
        told to, and the command's ACK confirms it (a disarm of a disarmed vehicle is accepted too):
        its next HEARTBEAT, ~1 wall s away and lost on a lossy link, is not waited for. An autopilot
        that refuses (its landing not finished) is given ``DISARM_WAIT`` more to disarm on its own - a
        PX4 rover is told again as soon as it reports itself landed (refused at rest, "not landed",
        one detected its landing 2.3 s later and disarmed itself 1.7 s after that)."""
        ctx = self.ctx
        end = ctx.clock() + DISARM_WAIT
        at_once = v.autopilot is not None and v.autopilot.disarm_when_landed

        def done_or_due(v: Vehicle) -> bool:
            down = v.on_ground is True or _at_rest(v)
            return not v.armed or v.lost or ctx.clock() >= end or (at_once and down)

        with contextlib.suppress(TimeoutError):
            await ctx.wait_for(v, done_or_due, DISARM_WAIT, "disarmed on the deck")
        if not v.armed or v.lost:
            return
        if await _disarm(ctx, v):
            return

        def landed(v: Vehicle) -> bool:  # refused (PX4 at rest: "Disarming denied: not landed")
            return not v.armed or v.lost or (at_once and v.on_ground is True)
        await ctx.wait_for(v, landed, DISARM_WAIT, "disarmed on the deck")
        if v.armed and not v.lost and not await _disarm(ctx, v):  # told again once it reports itself landed
            await ctx.wait_for(v, lambda v: not v.armed or v.lost, DISARM_WAIT, "disarmed on the deck")

    def _down_on_deck(self, rnd: _Round, v: Vehicle) -> bool:
        """``v``'s autopilot reports its landing done (at once; the landed state and positions come
        at the telemetry rate) right over the carrier (the last position: it came straight down)."""
        c = self.ctx.fleet.carrier
        seq = rnd.land_seq.get(v.name)
        if seq is None or seq not in v.items_reached or v.enu is None or c.enu is None:
            return False
        return math.hypot(v.enu[0] - c.enu[0], v.enu[1] - c.enu[1]) <= DECK_RADIUS

    async def _wait_meeting_point(self, rnd: _Round, v: Vehicle, leg_arrive: float, k: int, seq: int) -> bool:
        """Wait until ``v`` holds above its stop ``k`` (:meth:`_at_meeting_point`; MISSION_ITEM_REACHED
        comes at once, MISSION_CURRENT at its 1 Hz stream rate, the position shows it at rest on its
        hold when the reached message is lost) - or, while it flies there, the carrier parks more than
        ``RETARGET_OFFSET`` off the stop: then it is sent over the carrier (:meth:`_meet_over_carrier`)
        and True returned -: until it was due there (its release plus its planned flight) and the
        stated slack (:meth:`RunContext.late`), in mission time; a rover let go on the way ends the
        wait at once."""
        ctx, rid = self.ctx, v.name
        if rid in rnd.moved:  # sent over where the carrier comes to rest: out of its mission
            return True
        while True:
            losses = self.carrier.losses
            try:
                await ctx.wait_for(
                    v,
                    lambda v: (self._at_meeting_point(rnd, v) or rover_on_deck(ctx, v) or v.lost
                               or self._gone(rnd, v) or self._carrier_off_stop(rnd, v, k, seq) is not None),
                    ctx.late(max(rnd.due.get(rid, rnd.start + leg_arrive) - ctx.clock(), 0.0)),
                    "meeting point",
                )
                break
            except TimeoutError:
                if losses == self.carrier.losses and not self.carrier.lost:
                    raise
        found = self._carrier_off_stop(rnd, v, k, seq)
        if found is None or v.lost or self._at_meeting_point(rnd, v) or not self.board.in_round(rid):
            return False
        return await self._meet_over_carrier(rnd, v, found[1], k)

    # ============================================================================== letting go
    def _landing_places(self, rnd: _Round, rid: str) -> Callable[[], list[Vec3 | None]]:
        """Where ``rid`` may come down in this round: its stop (of the route flown now) and the carrier."""
        def places() -> list[Vec3 | None]:
            k = rnd.stop_of.get(rid)
            stops = rnd.stops
            stop = stops[k].position if k is not None and k < len(stops) else None
            return [stop, self.ctx.fleet.carrier.enu]
        return places

    def _gone(self, rnd: _Round, v: Vehicle) -> bool:
        """``v`` cannot arrive: let it go on the first evidence (idempotent; checked on each of
        its messages by every wait on it)."""
        rid = v.name
        if not self.board.in_round(rid):
            return self.board.status.get(rid) == RoverStatus.LET_GO
        trouble = rnd.trouble.get(rid)
        if trouble is None or v.lost or not trouble.seen(v):
            return False
        self._let_go(rnd, v, trouble.why or "cannot arrive")
        return True

    async def _watch(self, rnd: _Round, rid: str) -> None:
        """Watch ``rid`` for the whole round (also while it waits for its release)."""
        v = self.ctx.fleet.rovers[rid]
        with contextlib.suppress(TimeoutError):
            await v.wait_until(lambda v: self._gone(rnd, v) or not self.board.in_round(rid), WATCH_FOREVER,
                               "trouble")

    def _let_go(self, rnd: _Round, v: Vehicle, why: str) -> None:
        """``v`` leaves the round: journalled with the reason and where it is, no stop waits for
        it; the route is trimmed (a ``stranded`` event for the phase's loop)."""
        ctx, rid = self.ctx, v.name
        self.board.set(rid, RoverStatus.LET_GO)
        self.board.why[rid] = why
        self.supervisor.expect(rid, None)
        p = v.enu
        up = _airborne(v)
        pos = None if p is None else [round(c, 2) for c in p]
        ctx.state.set_state(rid, VehicleStatus.RETURNING if "RTL" in why else VehicleStatus.LANDED)
        ctx.state.event(
            Ev.ROVER_LET_GO,
            f"{rid}: {why}; let go, not collected (at {pos}, battery {v.battery_pct} %, "
            f"{'in the air' if up else 'on the ground'})",
            rid, reason=why, position=pos, battery_pct=v.battery_pct, landed=v.landed_state_name, mode=v.mode,
            airborne=up, at=ctx.clock(),
        )
        going = rnd.going.get(rid)
        if going is not None and not going.done() and going is not asyncio.current_task():
            going.cancel()
        self.supervisor.put(SupervisorEvent(Watch.STRANDED, rid, data={"why": why}))

    async def _trim(
        self, rnd: _Round, rest: list[Stop], rest_items: list[StopItems]
    ) -> tuple[list[Stop], list[StopItems]]:
        """The rest of a route without the rovers no longer in it: the others keep their meeting
        points; stops left empty are dropped and the carrier re-routed from where it is."""
        ctx = self.ctx
        keep: list[Stop] = []
        for s in rest:
            legs = [leg for leg in s.rovers if self.board.in_round(leg.rover)]
            if legs:
                keep.append(Stop(s.position, [], legs, s.arrive, s.depart))
        start, heading = self.carrier.pose()
        prev = start
        for s in keep:
            s.carrier_path = [prev, s.position]
            prev = s.position
        new = Plan(
            "collect",
            rnd.plan.planner,
            start,
            heading,
            keep,
            makespan=max((s.depart for s in keep), default=0.0),
            notes=["trimmed: lost rovers removed"],
        )
        rnd.start = ctx.clock()
        self._retime_round(rnd, new)
        if [s.position for s in keep] == [s.position for s in rest] and keep:
            ctx.replans.ready(new)  # the route itself is unchanged: no new command
            ctx.replans.finish(None)
            return keep, rest_items
        if not keep:
            ctx.replans.ready(None)
            return [], []
        await ctx.commit(Ev.PLAN, plan=new.to_json())
        compiled = self.planning.compile(new)
        ctx.replans.ready(new)
        await self.carrier.start_route(compiled)
        rnd.start = ctx.clock()
        ctx.state.set_plan(new.to_json(), rnd.start)
        return keep, list(compiled.stops)

    # ============================================================================== events
    def handle(self, ev: SupervisorEvent) -> bool:
        """Apply one supervision event; True when the rest of the route must be trimmed."""
        rid, board = ev.vehicle, self.board
        if ev.kind in (Watch.LOST, Watch.BACK) and rid == self.ctx.fleet.carrier_id:
            self.carrier.on_link(ev, lambda: board.with_status(RoverStatus.IN_ROUND))
            return False
        status = board.status.get(rid) if rid is not None else None
        if ev.kind == Watch.LOST and rid is not None and status not in (None, RoverStatus.LOADED):
            return self._on_rover_lost(ev, rid)
        if ev.kind == Watch.BACK and rid is not None and status == RoverStatus.LOST:
            board.set(rid, RoverStatus.PENDING)
            if rid in board.lost_at_start:
                board.lost_at_start.remove(rid)
            self.ctx.state.set_state(rid, VehicleStatus.ON_TASK)
            self.ctx.state.event(Ev.ROVER_REJOINED, f"{rid}: link back: rejoins the rovers to collect", rid)
            return False
        if ev.kind == Watch.TASKS:
            self.supervisor.reject("the deployment is over; tasks can change only while deploying", ev.source)
            return False
        if ev.kind == Watch.STRANDED and rid is not None and status == RoverStatus.LET_GO:
            self.ctx.replans.begin(f"{rid} let go: {ev.data.get('why')}", ev, self.plan)
            return True
        announce_warning(self.ctx, ev)
        if ev.kind == Watch.BATTERY_LOW and rid is not None and self.carrier.lost and board.in_round(rid):
            self.carrier.held.discard(rid)
            self.ctx.spawn(self.carrier.hold_or_land(self.ctx.fleet.rovers[rid], True), f"land {rid}")
        return False

    def _on_rover_lost(self, ev: SupervisorEvent, rid: str) -> bool:
        was_in_round = self.board.in_round(rid)
        self.board.set(rid, RoverStatus.LOST)
        self.ctx.state.set_state(rid, VehicleStatus.LOST)
        self.supervisor.expect(rid, None)
        if was_in_round:
            self.ctx.replans.begin(f"{rid} lost during the collection", ev, self.plan)
            return True
        return False

    # ============================================================================== the result
    def _finish(self, last_load: float | None) -> PhaseResult:
        self.ctx.state.set_state(self.ctx.fleet.carrier_id, VehicleStatus.IDLE)
        res = self.snapshot(last_load)
        if self.t0 is None:
            lost = self.board.lost_at_start
            self.ctx.state.event(
                Ev.NOTHING_TO_COLLECT, "no rover to collect" + (f" ({len(lost)} lost)" if lost else "")
            )
        return res

    def snapshot(self, last_load: float | None = None) -> PhaseResult:
        """The result as the board has it now (also after an interruption)."""
        board, res = self.board, self.result
        if last_load is None and board.loaded_at:
            last_load = max(board.loaded_at.values())
        ids = list(board.status)
        res.rovers_loaded = board.with_status(RoverStatus.LOADED)
        res.rovers_lost = board.with_status(RoverStatus.LOST)
        res.rovers_unreachable = board.with_status(RoverStatus.UNREACHABLE)
        res.rovers_let_go = {r: board.why.get(r, "cannot arrive")
                             for r in board.with_status(RoverStatus.LET_GO)}
        res.rovers_failed = {r: board.why.get(r, "not loaded in its round")
                             for r in board.with_status(RoverStatus.FAILED)}
        lost_at_start = set(board.lost_at_start)
        # complete: every rover loaded, except those out of reach, those let go (they cannot
        # arrive: reported with where they are) and those lost before it began
        res.complete = all(
            board.status[r] in (RoverStatus.LOADED, RoverStatus.UNREACHABLE, RoverStatus.LET_GO)
            or r in lost_at_start
            for r in ids
        )
        if self.t0 is None:  # nothing flown
            res.planned = 0.0
            res.complete = res.complete and not lost_at_start
        res.flown = (last_load if last_load is not None else 0.0) if res.complete else None
        return res


def _airborne(v: Vehicle) -> bool:
    """In the air by telemetry: its landed state, else its height."""
    if v.on_ground is not None:
        return not v.on_ground
    return (v.height or 0.0) > GROUND_HEIGHT


def _to_approach(z: float) -> float:
    """The least flight of a rover ``z`` m up: to the approach height above a stop under it."""
    return abs(max(z, 0.0) - MEET_HEIGHT)


__all__ = ["CollectPhase", "ResumedCollect", "RoverBoard", "RoverStatus"]
