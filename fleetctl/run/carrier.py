"""Carrier control: its live pose, its route (upload, arm, start), holding at a stop and release,
and what the fleet does while the carrier's link is down.

The carrier's route is a mission of a waypoint and an unlimited loiter per stop
(:mod:`fleetctl.mavlink.compile`); it holds at a stop until :meth:`CarrierControl.release` moves
its current item on. While the carrier is lost nothing is launched (:meth:`CarrierControl.ready`
waits), airborne rovers hold (or land when their battery is at the reserve) and resume when it
is back.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections.abc import Callable
from typing import Any

from fleetctl.mavlink.compile import CompiledPlan, is_waypoint, item_position
from fleetctl.mavlink.link import LinkError, MissionItem, MissionRejected
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle
from fleetctl.mission.flight import MEET_HEIGHT
from fleetctl.run.context import ExecutionError, RunContext
from fleetctl.run.kinds import Ev, VehicleStatus, Watch
from fleetctl.run.supervisor import SupervisorEvent

log = logging.getLogger(__name__)

STAY_RADIUS = 1.0  # m: a stopped carrier this near its new route's first stop stays on it
STAY_SPEED = 0.3  # m/s: a carrier this slow is stopped
CARRIER_OUTAGE_MAX = 600.0  # mission s the controller waits for a lost carrier to come back
# A collection lands rovers only on a carrier parked at their stop: stopped (STAY_SPEED) within
# PARK_RADIUS of it - beyond the 1.3 m beside the stop where an ArduRover that turned sharply into a
# short leg comes to rest, and the estimator's drift; the rovers are sent where the carrier brakes to
# while it comes in (fleetctl.run.collect.FOLLOW_STEP), and over it before they come down. A carrier
# seen beyond PARK_RADIUS or faster than DRIVE_OFF_SPEED has left its stop: a landing under way is
# broken off.
PARK_RADIUS = 3.0  # m
DRIVE_OFF_SPEED = 1.0  # m/s
# A carrier that does not stand still on its own is disarmed on its stop at this speed at most: PX4
# 1.18 SIH's Ackermann carrier, disarmed at 1 - 1.5 m/s, rolled on beyond PARK_RADIUS
HOLD_SPEED_MAX = 0.5  # m/s
# ... by its velocity estimate, or by its positions over this many seconds of its own clock (it moved
# HOLD_SPEED_MAX x HOLD_WINDOW m at most): the estimate of PX4 SIH's carrier read 0.54 - 0.83 m/s for
# 4 s while its position moved 0.06 m/s, and its rovers waited above it (collect +36 %)
HOLD_WINDOW = 1.0  # s
RESTOP_SETTLE = 10.0  # mission s on top of the drive back onto the stop (braking, turning, settling)
RESTOPS_MAX = 3  # waits for the carrier to park (each sending it back onto the stop when it is off it)

Vec3 = tuple[float, float, float]


async def upload(ctx: RunContext, v: Vehicle, items: list[MissionItem]) -> None:
    """Upload a mission to any vehicle; a rejection becomes an :class:`ExecutionError` naming it."""
    try:
        await ctx.command(v, "upload_mission", v.upload_mission(items), items=len(items))
    except MissionRejected as exc:
        why = f" ({exc.reason})" if exc.reason else ""
        raise ExecutionError(
            f"{v.name} ({ctx.fleet.urls.get(v.name, '')}) rejected its mission: {exc.result_name}{why}"
        ) from None


def stopped_on_item(v: Vehicle, seq: int) -> bool:
    """Telemetry shows ``v`` stopped (at most ``STAY_SPEED``) within ``STAY_RADIUS`` of its uploaded
    mission item ``seq``: its arrival there when both the MISSION_ITEM_REACHED and the MISSION_CURRENT
    that tell it at once were lost (the next MISSION_CURRENT comes about a wall second later).

    Not while it is nearer the waypoint before ``seq``: a carrier stops at every vertex of a roadmap
    path, and one of them may lie within ``STAY_RADIUS`` of the stop."""
    off, speed = _off(v, seq), v.ground_speed
    if off is None or off > STAY_RADIUS or speed is None or speed > STAY_SPEED:
        return False
    items = v.mission_items
    before = _off(v, seq - 1) if 0 < seq < len(items) and is_waypoint(items[seq - 1]) else None
    return before is None or off <= before


def hovering_on_item(v: Vehicle, seq: int) -> bool:
    """A rover's telemetry shows it at rest in the air (horizontal and vertical speed at most
    ``STAY_SPEED``) within ``STAY_RADIUS`` of its mission item ``seq`` (its hold above a meeting
    point): its arrival there when the MISSION_ITEM_REACHED that tells it at once was lost (the next
    MISSION_CURRENT comes about a wall second later: ten mission seconds at speed-up 10)."""
    vel = v.velocity
    return vel is not None and abs(vel[2]) <= STAY_SPEED and stopped_on_item(v, seq)


def _off(v: Vehicle, seq: int) -> float | None:
    """How far (m, horizontally) ``v`` is from its uploaded mission item ``seq``; None unknown."""
    items, origin, p = v.mission_items, v.origin, v.enu
    if p is None or origin is None or not 0 <= seq < len(items):
        return None
    x, y, _z = item_position(items[seq], origin)
    return math.hypot(p[0] - x, p[1] - y)


def parked_on_item(v: Vehicle, seq: int) -> bool:
    """Telemetry shows the carrier ``v`` parked at its mission item ``seq``: stopped (at most
    ``STAY_SPEED``) within ``PARK_RADIUS`` of it - where rovers may be sent down onto it."""
    off = _off(v, seq)
    speed = v.ground_speed
    return off is not None and off <= PARK_RADIUS and speed is not None and speed <= STAY_SPEED


async def climb_back(ctx: RunContext, v: Vehicle, stop: int) -> None:
    """The carrier left stop ``stop`` (counted from 1) under the landing of ``v``: the landing is
    broken off (journalled) and ``v`` climbs back to ``MEET_HEIGHT`` where it is and hovers."""
    text = f"{v.name}: the carrier left stop {stop}: landing broken off, hovering"
    ctx.record(Ev.ROVER_STATE, vehicle=v.name, text=text)
    ctx.state.set_state(v.name, VehicleStatus.WAITING)
    if v.position is None:
        return
    lat, lon, _alt = v.position
    await ctx.command(v, "goto", v.goto(lat, lon, MEET_HEIGHT))


def left_item(v: Vehicle, seq: int) -> bool:
    """The carrier ``v`` has left its mission item ``seq`` (beyond ``PARK_RADIUS`` or faster than
    ``DRIVE_OFF_SPEED``): a rover landing there must break off."""
    off = _off(v, seq)
    return (off is not None and off > PARK_RADIUS) or (v.ground_speed or 0.0) > DRIVE_OFF_SPEED


def standing(v: Vehicle) -> bool:
    """``v`` is slower than ``HOLD_SPEED_MAX`` by its velocity estimate or by its positions of the
    last ``HOLD_WINDOW`` seconds (:meth:`Vehicle.slower_than`): either shows a carrier that may be held."""
    return v.slower_than(HOLD_SPEED_MAX, HOLD_WINDOW)


class CarrierControl:
    """The carrier of one run (see the module docstring)."""

    def __init__(self, ctx: RunContext) -> None:
        self.ctx = ctx
        self.ok = asyncio.Event()  # cleared while the carrier's link is down
        self.ok.set()
        self.losses = 0  # carrier link losses so far (a wait that timed out during one is retried)
        self.held: set[str] = set()  # rovers paused while the carrier is lost
        self._stayed: int | None = None  # the first stop's arrive item when the route started there
        self._waiting = False  # the route was uploaded on its first stop and not started (start_route)
        self._held = False  # disarmed on its stop (hold_on_stop) and not moved on since
        self._parking = asyncio.Lock()  # one re-stop at a time, shared by the rovers of the stop

    @property
    def vehicle(self) -> Vehicle:
        return self.ctx.fleet.carrier

    @property
    def lost(self) -> bool:
        return self.vehicle.lost

    def pose(self) -> tuple[Vec3, float]:
        """The carrier's live ENU position (on the ground) and math heading; the mission's when
        telemetry lacks them."""
        c, m = self.vehicle, self.ctx.mission
        pos = c.enu
        start = (
            (pos[0], pos[1], 0.0) if pos is not None else (m.carrier.position[0], m.carrier.position[1], 0.0)
        )
        if c.heading_deg is not None:
            heading = math.radians(90.0 - c.heading_deg)
            heading = math.atan2(math.sin(heading), math.cos(heading))
        else:
            heading = math.radians(90.0 - m.carrier.heading_deg)
        return start, heading

    # -- the route ---------------------------------------------------------------------------------
    async def start_route(self, compiled: CompiledPlan) -> None:
        """Upload the route and start it. A carrier standing (stopped, within ``STAY_RADIUS``) at
        the route's first stop is armed, not started: it stays in its hold mode where it is and the
        stop counts as reached; its mission starts when it is released or sent back onto the stop
        (:meth:`_move_on`). Started on that stop's hold instead, an Ackermann carrier may drive off
        to reach the hold's point (PX4's SIH rover drove 4 m and once 57 m), and a replan that keeps
        the stop must not make it drive a loop back onto it."""
        c = self.vehicle
        await upload(self.ctx, c, list(compiled.carrier))
        stay = compiled.stops[0] if compiled.stops and self._standing_at(compiled, 0) else None
        self._stayed = None if stay is None else stay.arrive_seq
        self._waiting, self._held = stay is not None, False
        try:
            if not c.armed:  # armed as for its route (a disarmed PX4 SIH vehicle's clock runs at 1x)
                await self.ctx.command(c, "arm", c.arm())
            if not self._waiting:
                await self.ctx.command(c, "start_mission", c.start_mission(0))
        except CommandRejected as exc:
            raise ExecutionError(f"the carrier {c.name} refused to start its route: {exc}") from None
        except (LinkError, TimeoutError) as exc:
            raise ExecutionError(f"the carrier {c.name} did not answer: {exc}") from None

    def _standing_at(self, compiled: CompiledPlan, k: int) -> bool:
        c, origin = self.vehicle, self.vehicle.origin
        if c.enu is None or origin is None or (c.ground_speed or 0.0) > STAY_SPEED:
            return False
        x, y, _z = item_position(compiled.carrier[compiled.stops[k].arrive_seq], origin)
        return math.hypot(c.enu[0] - x, c.enu[1] - y) <= STAY_RADIUS

    async def release(self, stop: int, seq: int | None) -> None:
        """Let the carrier leave stop ``stop`` (0-based) by moving its mission on to ``seq``."""
        if seq is None:
            return
        c = self.vehicle
        try:
            await self._move_on(seq, "set_current", "start_mission", stop=stop + 1)
        except (CommandRejected, LinkError, TimeoutError) as exc:
            raise ExecutionError(f"the carrier {c.name} could not be released from its stop: {exc}") from None
        self.ctx.record(Ev.CARRIER_RELEASED, stop=stop + 1)

    async def _move_on(self, seq: int, label: str, start_label: str, **fields: Any) -> None:
        """Make item ``seq`` of the carrier's route current (journalled as ``label``) - or, when the
        route was not started (:meth:`start_route` on its first stop), start it there (armed first;
        journalled as ``start_label``)."""
        c = self.vehicle
        if not self._waiting:
            await self.ctx.command(c, label, c.set_current(seq), seq=seq, **fields)
            return
        if not c.armed:
            await self.ctx.command(c, "arm", c.arm())
        await self.ctx.command(c, start_label, c.start_mission(seq), seq=seq, **fields)
        self._waiting = self._held = False

    async def park(self) -> bool:
        """After a complete collection: the carrier in its hold mode and disarmed (armed, the next
        run's preflight would refuse it as flown by someone else). Journalled; a carrier that
        refuses or does not answer is reported, not an error. Returns whether it is disarmed."""
        c = self.vehicle
        if c.lost or not c.connected:
            return False
        try:
            await self.ctx.command(c, "hold_and_disarm", c.hold_and_disarm(self.ctx.wall(5.0)))
        except (CommandRejected, LinkError, TimeoutError) as exc:
            self.ctx.state.event(Ev.CARRIER_PARKED, f"{c.name}: could not disarm the carrier: {exc}", c.name,
                                 disarmed=False)
            return False
        self.ctx.state.event(Ev.CARRIER_PARKED, f"{c.name}: every rover loaded: carrier in HOLD and disarmed",
                             c.name, disarmed=True)
        return True

    async def reach_stop(self, k: int, arrive_seq: int, planned_leg: float) -> float:
        """Wait for the carrier to reach stop ``k`` (its mission clock time), waiting out carrier
        link outages on the way."""
        while True:
            losses = self.losses
            try:
                return await self._wait_stop(k, arrive_seq, planned_leg)
            except ExecutionError:
                if losses == self.losses and not self.lost:
                    raise
                await self.ready()

    async def _wait_stop(self, k: int, arrive_seq: int, planned_leg: float) -> float:
        c, st = self.vehicle, self.ctx.state
        st.stop_index = k + 1
        st.set_state(c.name, VehicleStatus.DRIVING)
        if self._stayed == arrive_seq and k == 0:  # standing there already (start_route)
            self._stayed = None
        else:
            try:
                await self.ctx.wait_for(
                    c,
                    lambda v: (arrive_seq in v.items_reached or (v.mission_current or -1) > arrive_seq
                               or stopped_on_item(v, arrive_seq)),
                    self.ctx.late(planned_leg),
                    f"mission item {arrive_seq}",
                )
            except TimeoutError as exc:
                raise ExecutionError(f"the carrier did not reach stop {k + 1}: {exc}") from None
        t = self.ctx.clock()
        st.set_state(c.name, VehicleStatus.HOLDING)
        st.event(
            Ev.STOP_REACHED,
            f"{c.name}: stop {k + 1}/{st.stop_count} reached",
            c.name,
            stop=k + 1,
            position=c.enu,
        )
        return t

    async def parked(self, k: int, seq: int, hold: bool = False) -> None:
        """Return once the carrier is parked at stop ``k`` (its arrive item ``seq``:
        :func:`parked_on_item`); a carrier not parked there is journalled (``carrier_off_stop``) and,
        when it is beyond ``PARK_RADIUS`` of the stop, sent back onto it (the stop's item made current
        again; once more when it stands still off the stop or is not back in time). Each wait is
        bounded in mission time: the drive back at the carrier's speed plus ``RESTOP_SETTLE``, with the
        stated slack (:meth:`RunContext.late`); after ``RESTOPS_MAX`` re-stops a ``TimeoutError``.
        ``hold``: the carrier is kept on the stop, disarmed (:meth:`hold_on_stop`), as soon as it may
        be (:meth:`_holdable`); disarmed there, it counts as parked. The rovers of
        the stop call this at once: one of them does the waiting, the rest find it done."""
        async with self._parking:
            for restops in range(RESTOPS_MAX + 1):
                c = self.vehicle
                if hold:
                    await self.hold_if_holdable(k, seq)
                if self.is_parked(seq):
                    return
                if restops == RESTOPS_MAX:
                    break
                await self.ready()
                off = _off(c, seq)
                self.ctx.record(Ev.CARRIER_OFF_STOP, vehicle=c.name, stop=k + 1, offset=off,
                                speed=c.ground_speed, attempt=restops + 1)
                budget = RESTOP_SETTLE
                if off is None or off > PARK_RADIUS:  # else it is still coming to a stop on it
                    await self._restop(k, seq)
                    budget += (off or 0.0) / max(self.ctx.mission.carrier.max_speed, 0.1)
                await self._wait_parked(k, seq, budget, hold)
            raise TimeoutError(f"the carrier is not parked at stop {k + 1} after {RESTOPS_MAX} re-stops")

    def is_parked(self, seq: int) -> bool:
        """The carrier is parked at its route's item ``seq`` (:func:`parked_on_item`), or disarmed
        on it (:meth:`hold_on_stop`) and within ``PARK_RADIUS``: its velocity estimate is not
        trusted then (see :meth:`_holdable`)."""
        c = self.vehicle
        if self._held:
            off = _off(c, seq)
            return off is not None and off <= PARK_RADIUS
        return parked_on_item(c, seq)

    def has_left(self, seq: int) -> bool:
        """The carrier has left its route's item ``seq`` (:func:`left_item`); disarmed on it, only
        when it is beyond ``PARK_RADIUS``."""
        c = self.vehicle
        if self._held:
            off = _off(c, seq)
            return off is not None and off > PARK_RADIUS
        return left_item(c, seq)

    async def hold_if_holdable(self, k: int, seq: int) -> None:
        """Disarm the carrier on stop ``k`` (its arrive item ``seq``) now if it may be
        (:meth:`_holdable`, :meth:`hold_on_stop`)."""
        if self._holdable(seq):
            await self.hold_on_stop(k)

    async def hold_once_holdable(self, k: int, seq: int) -> None:
        """Disarm the carrier on stop ``k`` (its arrive item ``seq``) as soon as it may be
        (:meth:`_holdable`), waiting at most ``RESTOP_SETTLE`` mission s for it to slow down: a
        carrier still rolling when it reaches its stop item is held the moment it stands, before
        it wanders off (PX4 1.18 SIH's Ackermann carrier reached a stop at 1.3 m/s, stood 0.5 s
        later, then circled the stop for 10 s until its rovers came in). The rovers' waits for the
        parked carrier (:meth:`parked`) go on as before; one that holds it first leaves this
        nothing to do."""
        try:
            await self.ctx.wait_for(self.vehicle, lambda _v: self._held or self._holdable(seq), RESTOP_SETTLE,
                                    f"the carrier standing on stop {k + 1}")
        except TimeoutError:
            return
        async with self._parking:
            if not self._held and self._holdable(seq):
                await self.hold_on_stop(k)

    @property
    def held_on_stop(self) -> bool:
        """The carrier is held disarmed on its stop (:meth:`hold_on_stop`) and has not moved on."""
        return self._held

    @property
    def stands_disarmed(self) -> bool:
        """The carrier's firmware does not stand it still on its own and it is held disarmed on its
        stops once it stands there (``Autopilot.stands_disarmed``: PX4's ground vehicles)."""
        ap = self.vehicle.autopilot
        return ap is not None and ap.stands_disarmed

    def _holdable(self, seq: int) -> bool:
        """The carrier may be disarmed on its stop (its arrive item ``seq``) now: parked there - or,
        on a firmware whose carrier does not stand still on its own (``Autopilot.stands_disarmed``),
        within ``PARK_RADIUS`` of it and slower than ``HOLD_SPEED_MAX`` (:func:`standing`). PX4 1.18
        SIH's Ackermann carrier, armed on its stop's loiter, read 0.3 - 0.5 m/s in its velocity estimate for
        seconds after it stopped while its position moved a few centimetres a second (a rover waited
        up to 5 s for it to read stopped), or circled the stop 1 - 2 m about it at 1.5 m/s, slowing
        down for moments.
        Disarmed on its stop it counts as parked, whatever its velocity estimate says."""
        c = self.vehicle
        if parked_on_item(c, seq):
            return True
        off = _off(c, seq)
        return self.stands_disarmed and off is not None and off <= PARK_RADIUS and standing(c)

    async def hold_on_stop(self, k: int) -> None:
        """Stop the carrier where it is, on stop ``k``, by disarming it: it drove off the stop under a
        landing and may not settle on its own - PX4 1.18's SIH Ackermann carrier circled a stop 2.1 m
        to its side at 1 m/s (three landings on it were broken off) and, switched to its hold mode,
        drove off 73 m. Disarmed, it stands. Its route goes on from the next stop armed again, with a
        mission start (as a route that began on its first stop: :meth:`start_route`). Refused:
        journalled, and it is left in its mission."""
        c = self.vehicle
        if not c.armed or self._held:
            return
        try:
            await self.ctx.command(c, "hold_on_stop", c.disarm(), stop=k + 1)
        except (CommandRejected, LinkError, TimeoutError) as exc:
            log.warning("%s: could not stop the carrier on stop %d: %s", c.name, k + 1, exc)
            return
        self._waiting = self._held = True

    async def _wait_parked(self, k: int, seq: int, budget: float, hold: bool = False) -> None:
        """Wait (``budget`` mission s with the stated slack) for the carrier parked at the stop (or,
        ``hold``, one it may be disarmed on: :meth:`_holdable` - PX4 SIH's carrier circling its stop
        for a minute, slowing down for moments, was never seen parked), lost, or - after it moved -
        standing still off the stop (it is sent back again)."""
        moved = False

        def done(v: Vehicle) -> bool:
            nonlocal moved
            speed = v.ground_speed or 0.0
            moved = moved or speed > STAY_SPEED
            off = _off(v, seq)
            return (parked_on_item(v, seq) or (hold and self._holdable(seq)) or v.lost
                    or (moved and speed <= STAY_SPEED and off is not None and off > PARK_RADIUS))

        with contextlib.suppress(TimeoutError):
            await self.ctx.wait_for(self.vehicle, done, self.ctx.late(budget),
                                    f"the carrier parked at stop {k + 1}")

    async def _restop(self, k: int, seq: int) -> None:
        """Send the carrier back onto stop ``k``: its arrive item ``seq`` made current again (it
        drives there and holds on the stop's loiter)."""
        c = self.vehicle
        try:
            await self._move_on(seq, "return_to_stop", "return_to_stop", stop=k + 1)
        except (CommandRejected, LinkError, TimeoutError) as exc:
            log.warning("%s: could not send the carrier back onto stop %d: %s", c.name, k + 1, exc)

    async def ready(self) -> None:
        """Wait (bounded) until the carrier's link is up."""
        if self.ok.is_set() and not self.lost:
            return
        try:
            await self.ctx.wait_for(self.vehicle, lambda v: not v.lost, CARRIER_OUTAGE_MAX, "carrier back")
        except TimeoutError:
            raise ExecutionError(
                f"the carrier {self.ctx.fleet.carrier_id} stayed lost for more than "
                f"{CARRIER_OUTAGE_MAX:g} s; rovers in the field hold where they are"
            ) from None

    # -- carrier outages ---------------------------------------------------------------------------
    def on_link(self, ev: SupervisorEvent, airborne: Callable[[], list[str]]) -> list[str]:
        """Carrier lost: no more launches, airborne rovers hold (or land when their battery is at
        the reserve); back: they resume. Returns the rovers sent to land."""
        if ev.kind == Watch.LOST:
            return self._lost(airborne())
        self._back()
        return []

    def _lost(self, airborne: list[str]) -> list[str]:
        ctx = self.ctx
        self.ok.clear()
        self.losses += 1
        reserve = ctx.mission.rovers.reserve * 100.0
        rovers = ctx.fleet.rovers
        landing: list[str] = []
        for rid in airborne:
            v = rovers[rid]
            if v.lost:
                continue
            low = v.battery_pct is not None and v.battery_pct <= reserve
            if low:
                landing.append(rid)
            else:
                self.held.add(rid)
            ctx.spawn(self.hold_or_land(v, low), f"hold {rid}")
        cid = ctx.fleet.carrier_id
        ctx.state.event(
            Ev.CARRIER_LOST,
            f"{cid}: carrier lost: no launches; airborne rovers hold "
            f"({', '.join(sorted(self.held)) or 'none'})",
            cid,
        )
        return landing

    def _back(self) -> None:
        ctx = self.ctx
        self.ok.set()
        held, self.held = sorted(self.held), set()
        for rid in held:
            ctx.spawn(self._resume(ctx.fleet.rovers[rid]), f"resume {rid}")
        cid = ctx.fleet.carrier_id
        ctx.state.event(Ev.CARRIER_BACK, f"{cid}: carrier back; resuming {', '.join(held) or 'nothing'}", cid)

    async def hold_or_land(self, v: Vehicle, low: bool) -> None:
        try:
            if low:
                await self.ctx.command(v, "land", v.land())
                self.ctx.state.event(
                    Ev.ROVER_LANDING, f"{v.name}: battery at the reserve, landing where it is", v.name
                )
            else:
                await self.ctx.command(v, "pause", v.pause())
        except (CommandRejected, LinkError, TimeoutError) as exc:
            log.warning("%s: could not hold/land: %s", v.name, exc)

    async def _resume(self, v: Vehicle) -> None:
        with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
            await self.ctx.command(v, "resume", v.resume())


__all__ = ["CARRIER_OUTAGE_MAX", "PARK_RADIUS", "CarrierControl", "climb_back", "left_item", "parked_on_item",
           "stopped_on_item", "upload"]
