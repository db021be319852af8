"""One rover's sortie in the air: its tasks' work (each reported done by the firmware's
MISSION_ITEM_REACHED of the item that timed it) and its way back to the pick-up stop, started at
the planned leave time moved by the operation's delay so far (:attr:`SortieFlight.leave_at`).

On an autopilot whose mission ends at a landing (ArduCopter: ``Autopilot.landing_ends_mission``)
a sortie flies in parts: a part ends on the ground at a task worked landed, the controller times
that work in mission time from the touch-down, then uploads, arms and starts the rest of the
sortie from there (``sortie_continued``)."""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

from fleetctl.aio import cancel_and_wait
from fleetctl.geo import local_to_geodetic
from fleetctl.mavlink.link import LinkError
from fleetctl.mavlink.sortie import ReturnItems, SortieItems, Visit, return_items, sortie_items
from fleetctl.mavlink.vehicle import (
    MISSION_STATE_COMPLETE,
    CommandRejected,
    Vehicle,
    VehicleEvent,
    VehicleEventKind,
)
from fleetctl.run.carrier import RESTOPS_MAX, STAY_SPEED, climb_back, left_item, upload
from fleetctl.run.context import ExecutionError, RunContext
from fleetctl.run.kinds import Ev, VehicleStatus
from fleetctl.run.launch import rover_on_deck
from fleetctl.run.operation.board import OperationBoard, SortieEntry, SortieStatus
from planners.operations import InFlight, OperationProblem, OpTask, air_needed
from planners.operations.plan import Sortie

Vec3 = tuple[float, float, float]
RECHECK = 1.0  # mission s between looks at the leave time (or the battery) while a rover waits (or works)
LAND_OFFSET = 1.0  # m: a rover waiting further off the stopped carrier lands at the carrier's position
CARRIER_STOP_WAIT = 10.0  # mission s for the carrier at its stop to come to rest before rovers land on it
REPLAN_SLACK = 15.0  # mission s: a task's work done this much earlier or later than planned asks for a replan
LANDED_WAIT = 10.0  # mission s from a task's approach waypoint to the touch-down of work timed on the ground
DISARM_WAIT = 5.0  # mission s for a firmware that ends its mission at a landing to disarm (ArduCopter: 1-2 s)
ON_TASK_RADIUS = 2.0  # m: a rover landed this near a task worked on the ground is at it (resume)


def landed_near(v: Vehicle, position: Vec3) -> bool:
    """On the ground within ON_TASK_RADIUS of ``position`` (at a task worked landed)."""
    p = v.enu
    return (p is not None and v.on_ground is True
            and math.hypot(p[0] - position[0], p[1] - position[1]) <= ON_TASK_RADIUS)


def item_passed(v: Vehicle, seq: int) -> bool:
    """Mission item ``seq`` is behind the firmware: its current item is past it, or it is the last
    one and the mission is complete (MISSION_STATE_COMPLETE, not ACTIVE: an item being flown is not
    passed) - what a controller that was down can still learn."""
    cur = v.mission_current
    return cur is not None and (cur > seq or (cur == seq and v.mission_state == MISSION_STATE_COMPLETE))


@dataclass(frozen=True)
class FlightClock:
    base: float  # operation s of the plan's time 0
    now: Callable[[], float]  # the operation clock
    delay: Callable[[], float]  # the operation's delay on its plan so far


@dataclass
class Pickup:
    """Where and when a rover is to come back: the stop (index in the plan flown), its position,
    and in operation seconds as planned: when the rover leaves its last task and is above the stop;
    ``aboard`` in the plan's own time; ``battery_left``: the fraction planned at touch-down."""

    stop: int
    position: Vec3
    leave: float
    meet: float
    aboard: float
    battery_left: float


class SortieFlight:
    """Flies one launched sortie to its end on the deck's approach (see the module docstring)."""

    def __init__(self, ctx: RunContext, board: OperationBoard, entry: SortieEntry, planned: Sortie,
                 items: SortieItems, pickup: Pickup, clock: FlightClock,
                 trouble: Callable[[str], None]) -> None:
        self.ctx, self.board, self.entry, self.planned = ctx, board, entry, planned
        self.items, self.pickup = items, pickup
        self.now, self.delay = clock.now, clock.delay  # operation clock; the operation's delay on its plan
        # task -> its planned arrival and end of work, operation s
        self.times = {v.task: (clock.base + v.arrive, clock.base + v.end) for v in planned.visits}
        self.trouble = trouble  # told when a task's work ends further off its plan than REPLAN_SLACK
        self.back: ReturnItems | None = None  # its way back, once uploaded and started
        self.reached_at: dict[int, float] = {}  # item -> operation s its MISSION_ITEM_REACHED came in
        self.problem: OperationProblem | None = None  # the mission's operation (its energy model), once asked
        self.battery_said = False  # a battery too low for the rest of the sortie was told (once a sortie)
        self.resumed = False  # flying the mission it had when the controller restarted (resume)
        self.dropped: set[str] = set()  # tasks a replan took off its sortie (called back early)
        self.low_battery: Callable[[str], None] = trouble  # told when its battery is too low for the rest

    def _on_event(self, ev: VehicleEvent) -> None:
        if ev.kind == VehicleEventKind.ITEM_REACHED and self.back is None:
            self.reached_at.setdefault(int(ev.data["seq"]), self.now())

    @property
    def vehicle(self) -> Vehicle:
        return self.ctx.fleet.rovers[self.entry.rover]

    def above_stop(self, v: Vehicle) -> bool:
        """Waiting above its pick-up stop (or lost: nobody waits for it)."""
        return v.lost or (self.back is not None and self.back.target_seq in v.items_reached)

    async def fly(self) -> None:
        unlisten = self.vehicle.add_listener(self._on_event)
        try:
            while True:
                for w in self.items.work:
                    if w.task in self.entry.tasks and w.task in self.board.tasks \
                            and self.board.tasks[w.task].done is None:
                        await self._work(w.task, w.arrive_seq, w.done_seq)
                rest = self._rest()
                if not rest:
                    break
                await self._continue(rest)
            if not self.dropped:  # called back: its firmware would fly on to a task dropped
                await self._wait_leave()
            await self._go_back()
        except (TimeoutError, LinkError, CommandRejected, ExecutionError) as exc:
            self._lost(str(exc))
        finally:
            unlisten()

    async def _work(self, task: str, arrive_seq: int, done_seq: int) -> None:
        ctx, v, st = self.ctx, self.vehicle, self.ctx.state
        rid, arrive = v.name, self.times[task][0]
        timed_here = task if done_seq < 0 else None  # the controller times its work on the ground
        await ctx.wait_for(v, lambda v: (self._reached(v, arrive_seq, timed_here) or v.lost
                                         or task in self.dropped),
                           ctx.late(arrive + self.delay() - self.now()), f"at task {task}")
        self._check(v)
        if task in self.dropped:
            return
        self.check_battery()
        work = self.board.tasks[task]
        st.set_state(rid, VehicleStatus.ON_TASK, task)
        if work.started is None or work.rover != rid:  # (a resumed sortie's work may have started before)
            work.rover, work.started, work.seen_start = rid, self.reached_at.get(arrive_seq, self.now()), True
            ctx.record(Ev.TASK_STARTED, vehicle=rid, task=task, sortie=self.entry.index)
        watch = asyncio.create_task(self._watch_battery(), name=f"battery {rid} at {task}")
        try:  # the battery looked at while it works, not only at the task's arrival and end
            if done_seq < 0:
                await self._work_on_ground(task, work.duration)
            else:
                await ctx.wait_for(v, lambda v: self._reached(v, done_seq) or v.lost or task in self.dropped,
                                   ctx.late(work.duration), f"work at {task} done")
        finally:
            await cancel_and_wait(watch)
        self._check(v)
        if task in self.dropped:
            return
        work.done = self.reached_at.get(done_seq, self.now())
        self.check_battery()
        off = work.done - (self.times[task][1] + self.delay())  # a replan on the way moved it
        if abs(off) > REPLAN_SLACK:
            self.trouble(f"task {task} done {off:+.0f} s off its plan")
        worked = round(work.done - work.started, 3) if work.seen_start else None  # None: firmware-timed
        how = f"{worked:.1f} s of work" if worked is not None else "started while the controller was down"
        st.event(Ev.TASK_DONE, f"{rid}: task {task} done ({how}, {work.duration:g} s asked)", rid, task=task,
                 sortie=self.entry.index, worked=worked, duration=work.duration)

    async def _watch_battery(self) -> None:
        while not self.battery_said:
            await self.ctx.sleep_mission(RECHECK)
            self.check_battery()

    def _reached(self, v: Vehicle, seq: int, task: str | None = None) -> bool:
        """Item ``seq`` of its sortie's mission reached (a resumed sortie also trusts the current
        item: its MISSION_ITEM_REACHED may have come while the controller was down, and a rover
        landed at a task whose work the controller times)."""
        if seq in v.items_reached:
            return True
        if not self.resumed or self.back is not None:
            return False
        return item_passed(v, seq) or (task is not None and self._landed_at(v, task))

    def _landed_at(self, v: Vehicle, task: str) -> bool:
        """On the ground within ON_TASK_RADIUS of ``task`` (a task worked landed)."""
        visit = next((x for x in self.planned.visits if x.task == task), None)
        return visit is not None and landed_near(v, visit.position)

    async def _work_on_ground(self, task: str, duration: float) -> None:
        """Work timed by the controller (its firmware ends the mission at the landing): ``duration``
        mission seconds from the touch-down, the rover and the call-back looked at every RECHECK."""
        ctx, v = self.ctx, self.vehicle
        await ctx.wait_for(v, lambda v: v.on_ground is True or v.lost or task in self.dropped,
                           ctx.late(LANDED_WAIT), f"landed at {task}")
        end = self.now() + duration
        while (left := end - self.now()) > 0 and not v.lost and task not in self.dropped:
            await ctx.sleep_mission(min(RECHECK, left))

    def _rest(self) -> list[Visit]:
        """The tasks of the sortie still to fly after its mission's last part, which ended on the
        ground at a task whose work the controller timed (none otherwise, or once called back)."""
        work = self.items.work
        if not work or work[-1].done_seq >= 0 or self.dropped:
            return []
        flown = {w.task for w in work}
        visits = {x.task: x for x in self.planned.visits}
        tasks = self.board.tasks
        return [Visit(t, visits[t].position, tasks[t].duration, visits[t].ground) for t in self.entry.tasks
                if t not in flown and t in visits and t in tasks and tasks[t].done is None]

    async def _continue(self, rest: list[Visit]) -> None:
        """The rest of the sortie from the task on the ground where its last part ended: uploaded,
        armed (the firmware disarmed at the landing) and started."""
        ctx, v = self.ctx, self.vehicle
        self._check(v)
        if v.origin is None or v.enu is None:
            raise ExecutionError(f"{v.name}: no position to fly the rest of its sortie from")
        await self._settle_on_ground(v)
        items = sortie_items(v.name, v.enu, rest, v.origin, v.autopilot, takeoff_from=v.enu)
        await upload(ctx, v, list(items.items))
        if not v.armed:
            await ctx.command(v, "arm", v.arm())
        first = 1 if v.autopilot is not None and v.autopilot.home_is_item0 else 0
        await ctx.command(v, "start_mission", v.start_mission(first))
        self.items = items
        self.reached_at.clear()
        ctx.state.set_state(v.name, VehicleStatus.EN_ROUTE, rest[0].task)
        ctx.state.event(Ev.SORTIE_CONTINUED, f"{v.name}: sortie {self.entry.index} goes on to "
                        f"{', '.join(x.task for x in rest)}", v.name, sortie=self.entry.index,
                        tasks=[x.task for x in rest],
                        work=[[w.task, w.arrive_seq, w.done_seq] for w in items.work])

    async def _settle_on_ground(self, v: Vehicle) -> None:
        """A firmware that ends its mission at a landing disarms on its own about a second or two
        after the touch-down: wait for it (DISARM_WAIT at most) before a new mission is started, so
        that the disarm does not come after the new arming."""
        ap = v.autopilot
        if ap is None or not ap.landing_ends_mission or not v.armed or v.on_ground is not True:
            return
        with contextlib.suppress(TimeoutError):
            await self.ctx.wait_for(v, lambda v: not v.armed or v.lost, DISARM_WAIT, "disarmed after landing")

    async def _wait_leave(self) -> None:
        while self.now() < self.pickup.leave + self.delay():
            self._check(self.vehicle)
            self.check_battery()
            await self.ctx.sleep_mission(min(RECHECK, self.pickup.leave + self.delay() - self.now()))

    def work_left(self) -> list[tuple[str, float]]:
        """Its tasks not done with their work left (the one being worked: what it still needs)."""
        now = self.now()
        return [(t, self.board.tasks[t].duration - self.board.tasks[t].worked(now))
                for t in self.entry.tasks if self.board.tasks[t].done is None]

    def battery_needed(self) -> float | None:
        """The battery fraction the rest of the sortie needs from here, its reserve included: the
        flights to its tasks left and their work, the way back to its pick-up stop leaving the last
        task at once (None: no position to reckon from)."""
        v = self.vehicle
        if v.enu is None:
            return None
        if self.problem is None:
            self.problem = self.ctx.mission.operation_problem()
        p, visits = self.problem, {x.task: x for x in self.planned.visits}
        left = tuple(OpTask(t, visits[t].position, max(w, 0.0), visits[t].ground)
                     for t, w in self.work_left())
        here = (v.enu[0], v.enu[1], max(v.enu[2], 0.0))
        need = air_needed(p, InFlight(v.name, here, left, 0.0, v.on_ground is True), self.pickup.position)
        return need / p.endurance + p.reserve

    def check_battery(self) -> None:
        """A battery reading below what the rest of the sortie needs asks the phase for a replan
        from the live state (once a sortie)."""
        frac = self.vehicle.battery_fraction
        if self.battery_said or frac is None:
            return
        need = self.battery_needed()
        if need is not None and frac < need:
            self.battery_said = True
            self.low_battery(f"rover {self.entry.rover} at {100 * frac:.0f} % of its battery in the air, "
                         f"{100 * need:.0f} % needed for the rest of its sortie, the way back and "
                         "the reserve")

    def drop(self, tasks: list[str], stop: int) -> None:
        """A replan called it back early: ``tasks`` are no longer its own (work on them stops and
        is done again in full by others); it flies back to its pick-up ``stop`` once the tasks it
        keeps are done."""
        tasks = [t for t in tasks if t in self.entry.tasks]
        if not tasks:
            return
        for t in tasks:
            self.entry.tasks.remove(t)
            w = self.board.tasks.get(t)
            if w is not None and w.done is None:
                w.started = w.rover = None
        self.dropped.update(tasks)
        rid = self.entry.rover
        self.ctx.state.event(Ev.SORTIE_CALLED_BACK, f"{rid}: called back early from sortie "
                             f"{self.entry.index} (battery too low): dropped {', '.join(tasks)}; keeps "
                             f"{', '.join(self.entry.tasks) or 'none'}", rid, sortie=self.entry.index,
                             tasks=tasks, kept=list(self.entry.tasks), stop=stop + 1)

    def retarget(self, pickup: Pickup, planned: Sortie, base: float) -> None:
        """A replan's pick-up and times (``planned``: its sortie in the new plan, whose time 0 is
        ``base``); a rover already on its way back is sent to the new stop."""
        moved = pickup.position != self.pickup.position
        self.pickup = pickup
        self.times.update({v.task: (base + v.arrive, base + v.end) for v in planned.visits if v.task})
        if self.back is not None and moved:
            self.ctx.spawn(self._resend(), f"back {self.entry.rover}")

    async def _resend(self) -> None:
        try:
            await self._go_back()
        except (TimeoutError, LinkError, CommandRejected, ExecutionError) as exc:
            self._lost(str(exc))

    async def _go_back(self) -> None:
        ctx, v = self.ctx, self.vehicle
        origin = v.origin
        if origin is None or v.enu is None:
            raise ExecutionError(f"{v.name}: no position to fly back from")
        ground = v.on_ground is True
        if ground:
            await self._settle_on_ground(v)
        ret = return_items(v.enu, ground, self.pickup.position, origin, v.autopilot)
        await upload(ctx, v, list(ret.items))
        if not v.armed:  # a firmware that disarmed it landed at its task
            await ctx.command(v, "arm", v.arm())
        first = 1 if v.autopilot is not None and v.autopilot.home_is_item0 else 0
        await ctx.command(v, "start_mission", v.start_mission(first))
        self.back = ret
        self.entry.status = SortieStatus.RETURNING
        ctx.state.set_state(v.name, VehicleStatus.RETURNING)
        ctx.record(Ev.SORTIE_RETURNING, vehicle=v.name, sortie=self.entry.index, stop=self.pickup.stop + 1)

    def _check(self, v: Vehicle) -> None:
        if v.lost:
            raise ExecutionError(f"{v.name}: link lost")

    def _lost(self, why: str) -> None:
        rid = self.entry.rover
        if self.entry.status is SortieStatus.LOST:
            return
        self.entry.status = SortieStatus.LOST
        if rid not in self.board.lost:
            self.board.lost.append(rid)
        self.ctx.state.set_state(rid, VehicleStatus.LOST)
        left = [t for t in self.entry.tasks if self.board.tasks[t].done is None]
        for t in left:  # the work of a lost rover is lost with it: another does the whole task again
            self.board.tasks[t].started = self.board.tasks[t].rover = None
        self.ctx.state.event(Ev.SORTIE_LOST, f"{rid}: sortie {self.entry.index} lost ({why}); "
                             f"work left: {', '.join(left) or 'none'}", rid, sortie=self.entry.index,
                             tasks_left=left, reason=why)
        self.trouble(f"rover {rid} lost")


async def land_on_deck(ctx: RunContext, flight: SortieFlight, timeout: float, stop_seq: int,
                       parked: Callable[[], Awaitable[None]]) -> bool:
    """Send a rover waiting above the carrier down onto its deck once the carrier has stopped (its
    stop's waypoint is reached before it has braked); a rover hovering more than ``LAND_OFFSET`` off
    the carrier lands at the carrier's position instead of its stop's. A carrier that leaves its
    stop (its route's item ``stop_seq``: :func:`fleetctl.run.carrier.left_item`) during the descent
    breaks the landing off: the rover climbs back to ``MEET_HEIGHT`` where it is and hovers until
    the carrier is parked on the stop again (``parked``), then comes down over it; at most
    ``RESTOPS_MAX`` times. True once it is on the deck."""
    v, c = flight.vehicle, ctx.fleet.carrier
    if flight.back is None or v.lost:
        return False
    for attempt in range(RESTOPS_MAX):
        with contextlib.suppress(TimeoutError):
            await ctx.wait_for(c, lambda c: (c.ground_speed or 0.0) <= STAY_SPEED, CARRIER_STOP_WAIT,
                               "stopped")

        def down_or_left(v: Vehicle) -> bool:
            on_deck = v.on_ground is True and rover_on_deck(ctx, v)
            return v.lost or on_deck or (left_item(c, stop_seq) and v.on_ground is not True)

        try:
            await _send_down(ctx, flight, over_carrier=attempt > 0)
            await ctx.wait_for(v, down_or_left, timeout, "on the deck")
        except (CommandRejected, LinkError, TimeoutError):
            return False
        if v.lost or (v.on_ground is True and rover_on_deck(ctx, v)):
            return not v.lost
        with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
            await climb_back(ctx, v, flight.pickup.stop + 1)  # the carrier left its stop under the landing
        try:
            await parked()
        except TimeoutError:
            return False
    return False


async def _send_down(ctx: RunContext, flight: SortieFlight, over_carrier: bool) -> None:
    """Its way back's landing item (or its landing mode where that item would settle first:
    ``Autopilot.mission_landing_settles``), or - hovering more than LAND_OFFSET off the carrier, or
    after a landing broken off (out of its mission) - a landing at the carrier's position."""
    v, back, c = flight.vehicle, flight.back, ctx.fleet.carrier
    assert back is not None
    if c.enu is not None and c.origin is not None and v.enu is not None and (
            over_carrier or math.hypot(v.enu[0] - c.enu[0], v.enu[1] - c.enu[1]) > LAND_OFFSET):
        lat, lon, _alt = local_to_geodetic(c.enu[0], c.enu[1], 0.0, c.origin)
        await ctx.command(v, "land", v.land(lat, lon))
    elif v.autopilot is not None and v.autopilot.mission_landing_settles:
        await ctx.command(v, "land", v.land())  # straight down where it hovers, at once
    else:
        await ctx.command(v, "land", v.set_current(back.land_seq), seq=back.land_seq)


__all__ = ["REPLAN_SLACK", "FlightClock", "Pickup", "SortieFlight", "item_passed", "land_on_deck",
           "landed_near"]
