"""The operation phase: plan the operation (``planners.operations``), then walk the plan's carrier
stops. At each stop the carrier waits for the rovers it picks up (each above the stop on its way
back, :class:`~fleetctl.run.operation.sortie.SortieFlight`), sends them down onto the deck, loads
them (``load_time``), queues their battery swaps (:class:`~fleetctl.run.operation.swaps.SwapStation`),
launches the stop's sorties (:class:`~fleetctl.run.launch.Launcher`: deck check, upload, arm,
start when unloading ends, lift-off) and is released to the next stop. Every wait is a deadline
in mission time; the operation's delay on its plan (measured at each stop) moves the rovers'
leave times so that they meet the carrier when it is there."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import time
from collections.abc import Awaitable, Callable
from typing import Any

from fleetctl.aio import cancel_and_wait
from fleetctl.mavlink.compile import RoverMission
from fleetctl.mavlink.link import LinkError
from fleetctl.mavlink.sortie import SortieItems, Visit, route_items, sortie_items
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle
from fleetctl.run.carrier import upload
from fleetctl.run.context import ExecutionError
from fleetctl.run.events import next_event
from fleetctl.run.kinds import Ev, Phase, VehicleStatus, Watch
from fleetctl.run.launch import Launcher, Spares, rover_on_deck
from fleetctl.run.operation.board import (
    OperationBoard,
    SortieEntry,
    SortieStatus,
    TaskWorkState,
    sorties_ahead,
)
from fleetctl.run.operation.changes import TaskChanges
from fleetctl.run.operation.live import live_problem
from fleetctl.run.operation.resume import OperationReplay
from fleetctl.run.operation.sortie import FlightClock, Pickup, SortieFlight, land_on_deck
from fleetctl.run.operation.swaps import SwapStation
from fleetctl.run.parts import PhaseParts
from fleetctl.run.results import PhaseResult
from fleetctl.run.state import OperationProgress
from fleetctl.run.supervisor import SupervisorEvent
from fleetctl.run.task_board import TaskBoard
from planners.core.problem import PlanningError
from planners.operations import OperationPlan, OperationProblem, plan_operation
from planners.operations.plan import OpStop, Sortie
from planners.operations.plan import Visit as PlanVisit

log = logging.getLogger(__name__)

PlanWriter = Callable[[str, dict[str, Any]], None]  # (file name in the run folder, plan JSON)
LANDING_TIMEOUT = 20.0  # mission s from the land command to the rover on the deck
SWAP_EPS = 1e-6
BATTERY_READ_WAIT = 1.0  # wall s for each rover's fresh battery reading before a replan
REPLAN_ROUNDS = 20  # the planner's perturbed rounds in a replan (rovers in the air fly on meanwhile)
ROUTE_START_WAIT = 5.0  # mission s for a carrier to report the new route's first item current
BATTERY_SLACK = 0.02  # of a battery: a next sortie that would end this near the reserve asks for a replan
# trouble while the carrier drives replans at once (the carrier paused where it is) when the plan has it
# at least this long (mission s) from its next stop; nearer, the replan waits for the stop
DRIVE_REPLAN_MIN = 5.0
PAUSED_SPEED = 0.2  # m/s: a paused carrier this slow is where the replan starts from
PAUSE_WAIT = 10.0  # mission s for the paused carrier to come to rest
WATCH_POLL = 1.0  # wall s between looks at the drive's trouble when nothing else wakes the watch


class OperationPhase:
    """One long operation (see the module docstring)."""

    def __init__(self, parts: PhaseParts, write_plan: PlanWriter | None = None,
                 live_tasks: TaskBoard | None = None) -> None:
        self.ctx, self.carrier, self.supervisor = parts.ctx, parts.carrier, parts.supervisor
        self.live_tasks = live_tasks if live_tasks is not None else TaskBoard.of(parts.ctx.mission.tasks)
        self.write_plan = write_plan
        self.board = OperationBoard()
        self.plan: OperationPlan | None = None
        self.t0: float | None = None
        self.delay = 0.0  # operation s the flight is behind its plan (at the last stop reached)
        self.flights: dict[str, SortieFlight] = {}  # rover -> its sortie in the air
        self.base = 0.0  # operation s of the plan flown's time 0 (a replan's plan starts at its making)
        self.entry_of: dict[int, SortieEntry] = {}  # the plan flown's sortie index -> its board entry
        self.trouble: str | None = None  # why to replan (at the next stop, or on the way: _drive)
        self.troubled = asyncio.Event()  # set with each cause of trouble (wakes a drive's watch)
        self.urgent = False  # a rover in the air short of battery: replan, not waiting for pick-ups
        self.changes = TaskChanges(self.ctx, self.board, {}, self.live_tasks)
        self.swaps = SwapStation(self.ctx, self.board, self.now)
        self.result = PhaseResult("operation")

    def now(self) -> float:
        """Operation seconds since the carrier started its route."""
        return 0.0 if self.t0 is None else self.ctx.clock() - self.t0

    # ============================================================================== the walk
    async def run(self) -> PhaseResult:
        ctx = self.ctx
        ctx.state.set_phase(Phase.PLAN)
        await ctx.wait_telemetry()
        problem = self._problem()
        try:
            plan: OperationPlan | None = await asyncio.to_thread(plan_operation, problem)
        except PlanningError as exc:
            raise ExecutionError(f"cannot plan the operation with the rovers on the deck "
                                 f"({', '.join(problem.rovers)}): {exc}") from None
        assert plan is not None
        self.board.tasks = {t.id: TaskWorkState(t.duration) for t in problem.tasks}
        self.changes = TaskChanges(ctx, self.board, {t.id: t for t in problem.tasks}, self.live_tasks)
        self.supervisor.start()  # task changes (the mission file, MQTT) come in on its queue
        self._adopt(plan, "plan.json")
        ctx.record(Ev.PLAN, plan="operation", planner=plan.planner, makespan=round(plan.makespan, 3),
                   stops=len(plan.stops), sorties=len(plan.sorties), swaps=len(plan.swaps))
        self.result.planned = plan.makespan
        ctx.state.set_phase(Phase.OPERATION, plan.makespan, len(plan.stops))
        ctx.state.operation = self._progress
        while plan is not None:
            plan = await self._walk(plan)
        return self._finish()

    async def resume(self, rep: OperationReplay) -> PhaseResult:
        """Finish an interrupted operation (``fleetctl resume``): the journal's board, reconciled
        with the live fleet (:mod:`.resume`), replanned from the live state and flown on."""
        ctx = self.ctx
        if rep.started_unix is None:  # the carrier never started: nothing flew, plan it afresh
            return await self.run()
        ctx.state.set_phase(Phase.PLAN)
        await ctx.wait_telemetry()
        self.board.restore(rep.board)
        self.t0 = ctx.clock() - rep.elapsed(time.time())
        self.result.started, self.result.planned = self.t0, rep.planned
        self.changes = TaskChanges(ctx, self.board, dict(rep.tasks), self.live_tasks)
        self.changes.added, self.changes.removed = list(rep.added), list(rep.removed)
        self.supervisor.start()
        ctx.state.replans = rep.replans
        for rid, entry in rep.in_air.items():
            self.flights[rid] = self._resumed_flight(entry, rep)
        ctx.state.set_phase(Phase.OPERATION, rep.planned, 0)
        ctx.state.operation = self._progress
        self.trouble = "resumed after the controller restarted"
        plan = await self._replan()
        if plan is None and (self.flights or self.board.left()):
            raise ExecutionError("cannot plan the rest of the interrupted operation from the live state")
        for rid, f in self.flights.items():
            ctx.spawn(f.fly(), f"sortie {f.entry.index} {rid}")
        while plan is not None:
            plan = await self._walk(plan)
        return self._finish()

    def _resumed_flight(self, entry: SortieEntry, rep: OperationReplay) -> SortieFlight:
        """A sortie found in the air on resume, flying the mission its rover holds (its new
        pick-up comes with the replan)."""
        visits = [PlanVisit(t, self.changes.tasks[t].position, 0.0, 0.0, 0.0, self.changes.tasks[t].ground)
                  for t in entry.tasks if t in self.changes.tasks]
        here = self.carrier.pose()[0]
        items = SortieItems(entry.rover, (), 0, rep.work.get(entry.index, ()))
        pickup = Pickup(0, here, self.now(), self.now(), 0.0, 0.0)
        flight = SortieFlight(self.ctx, self.board, entry, Sortie(entry.rover, -1, 0.0, 0.0, visits), items,
                              pickup, FlightClock(self.base, self.now, lambda: self.delay), self._on_trouble)
        flight.resumed = True
        flight.dropped = {w.task for w in items.work if w.task not in entry.tasks}  # called back before
        flight.low_battery = self._on_low_battery
        self.ctx.state.set_state(entry.rover, VehicleStatus.EN_ROUTE if entry.status is SortieStatus.FLYING
                                 else VehicleStatus.RETURNING)
        return flight

    async def _walk(self, plan: OperationPlan) -> OperationPlan | None:
        """Fly ``plan``'s stops; the plan of a replan made on the way (None: flown to its end)."""
        seqs = await self._start_route(plan)
        self.ctx.state.stop_count = len(plan.stops)
        for k, stop in enumerate(plan.stops):
            leg = stop.arrive - (plan.stops[k - 1].depart if k else 0.0)
            if not await self._drive(k, seqs[k][0], leg, stop):
                if (new := await self._replan_on_the_way()) is not None:
                    return new
                await self.carrier.reach_stop(k, seqs[k][0], leg)
            self.delay = max(self.now() - (self.base + stop.arrive), 0.0)
            self.ctx.state.eta = self._eta()
            waiting = await self._pick_up(k, seqs[k][0], stop, interruptible=True)
            self._take_changes()
            await self._check_batteries()
            if self.trouble is not None and (new := await self._replan()) is not None:
                return new
            if waiting:  # a replan that found no plan: the stop's pick-ups as planned
                await self._pick_up(k, seqs[k][0], stop, interruptible=False)
            await self._launch(k, stop)
            if seqs[k][1] is not None:
                await self.carrier.release(k, seqs[k][1])
        if plan.recovery and self.board.left():  # the rovers it brought back are aboard: the rest
            self._on_trouble("the rovers called back by a recovery plan are aboard")
            return await self._replan()
        return None

    def _problem(self) -> OperationProblem:
        """The mission's operation for the rovers that answered and are on the deck."""
        ctx = self.ctx
        problem = ctx.mission.operation_problem()
        rovers = tuple(r for r in problem.rovers if rover_on_deck(ctx, ctx.fleet.rovers[r]))
        if not rovers:
            raise ExecutionError("no rover on the carrier's deck to fly the operation with")
        return dataclasses.replace(problem, rovers=rovers)

    def _eta(self) -> float | None:
        """The operation's end the flight heads for, in mission s of the phase: the plan's end
        moved by the delay so far."""
        st, plan = self.ctx.state, self.plan
        if plan is None or st.phase_started is None or self.t0 is None:
            return None
        return self.t0 - st.phase_started + self.base + plan.makespan + self.delay

    def _progress(self) -> OperationProgress:
        now = self.now()
        at = now - self.base - self.delay  # where the flight is on the plan's clock
        ahead = () if self.plan is None else sorties_ahead(self.plan, self.entry_of, at)
        return self.board.progress(now, self._eta(), ahead)

    def _adopt(self, plan: OperationPlan, name: str) -> None:
        """Fly ``plan`` from now on: its sorties on the board, the rovers in the air told their new
        pick-up, the plan written to the run folder as ``name``."""
        self.plan, self.base = plan, self.now()
        self.entry_of = {}
        for i, s in enumerate(plan.sorties):
            if s.launch_stop >= 0:
                self.entry_of[i] = self.board.new_sortie(s.rover, [v.task for v in s.visits])
            elif s.rover in self.flights:  # in the air before this plan
                self.flights[s.rover].drop(plan.called_back.get(s.rover, []), s.pickup_stop)
                self.flights[s.rover].retarget(self._pickup(plan, s), s, self.base)
        if self.write_plan is not None:
            self.write_plan(name, plan.to_json())

    def _pickup(self, plan: OperationPlan, s: Sortie) -> Pickup:
        return Pickup(s.pickup_stop, plan.stops[s.pickup_stop].position, self.base + s.visits[-1].leave,
                      self.base + s.meet, s.aboard, s.battery_left)

    def _take_changes(self) -> None:
        """Task changes queued since the last look (other supervision events are seen by the
        sorties themselves)."""
        while not self.supervisor.queue.empty():
            self._take_change(self.supervisor.queue.get_nowait())

    def _take_change(self, ev: SupervisorEvent) -> None:
        flying = [t for f in self.flights.values() if f.entry.status is SortieStatus.FLYING
                  for t, _w in f.work_left()]
        if ev.kind == Watch.TASKS and self.changes.apply(ev, flying):
            self._on_trouble(f"tasks changed by {ev.source}")

    # ============================================================================== on the way
    async def _drive(self, k: int, seq: int, leg: float, stop: OpStop) -> bool:
        """Drive to stop ``k`` (its arrive item ``seq``, ``leg`` mission s planned). False: trouble
        came on the way with the carrier still ``DRIVE_REPLAN_MIN`` or more from the stop (the
        replan is then made at once, :meth:`_replan_on_the_way`, not at the stop)."""
        reach = asyncio.ensure_future(self.carrier.reach_stop(k, seq, leg))
        watch = asyncio.ensure_future(self._watch_the_way(stop))
        try:
            await asyncio.wait({reach, watch}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            await cancel_and_wait(watch, reach)
        if reach.done() and not reach.cancelled():
            reach.result()  # its ExecutionError, if it failed
            return True
        return False

    def _drive_left(self, stop: OpStop) -> float:
        """Mission s the plan (shifted by the delay so far) still gives the drive to ``stop``."""
        return self.base + stop.arrive + self.delay - self.now()

    async def _watch_the_way(self, stop: OpStop) -> None:
        """Return when there is trouble (a task change, a rover lost or short of battery) and the
        carrier is still far enough from ``stop`` for a replan on the way."""
        while True:
            self._take_changes()
            if self.trouble is not None and self._drive_left(stop) >= DRIVE_REPLAN_MIN:
                return
            self.troubled.clear()
            woke: asyncio.Task[Any] = asyncio.ensure_future(self.troubled.wait())
            try:
                ev = await next_event(self.supervisor.queue, {woke}, WATCH_POLL)
            finally:
                await cancel_and_wait(woke)
            if ev is not None:
                self._take_change(ev)

    async def _replan_on_the_way(self) -> OperationPlan | None:
        """Pause the carrier where it is and replan from there; no new plan: it drives on."""
        c = self.carrier.vehicle
        self.ctx.state.event(Ev.HOLD, f"{c.name}: paused on its way for a replan ({self.trouble})", c.name,
                             vehicles=[c.name])
        with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
            await self.ctx.command(c, "pause", c.pause())
            await self.ctx.wait_for(c, lambda v: (v.ground_speed or 0.0) < PAUSED_SPEED, PAUSE_WAIT,
                                    "the carrier paused")
        new = await self._replan()
        if new is None:
            with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
                await self.ctx.command(c, "resume", c.resume())
        return new

    async def _check_batteries(self) -> None:
        """The rovers in the air with a fresh battery reading each (a streamed one is a second of
        wall time old): one reading lower than the rest of its sortie needs asks for a replan."""
        flights = [f for f in self.flights.values() if f.entry.status is SortieStatus.FLYING
                   and not f.vehicle.lost]
        await asyncio.gather(*(f.vehicle.refresh_battery(BATTERY_READ_WAIT) for f in flights))
        for f in flights:
            f.check_battery()

    def _interrupt(self, interruptible: bool) -> bool:
        return self.urgent and interruptible

    def _above_or_urgent(self, f: SortieFlight, interruptible: bool) -> Callable[[Vehicle], bool]:
        return lambda v: f.above_stop(v) or self._interrupt(interruptible)

    def _on_low_battery(self, cause: str) -> None:
        """A rover in the air short of battery for the rest of its sortie: replan at once (a stop
        waiting for its pick-ups stops waiting), so that it can be called back early."""
        self.urgent = True
        self._on_trouble(cause)

    def _on_trouble(self, cause: str) -> None:
        """A rover lost, a task's work off its plan, ...: replan at the next stop, or on the way when
        the carrier is still far from it (every cause said)."""
        if self.trouble is None:
            self.trouble = cause
        elif cause not in self.trouble:
            self.trouble += f"; {cause}"
        self.troubled.set()

    async def _replan(self) -> OperationPlan | None:
        """The rest of the operation planned from the live state (None: nothing to plan, or no
        plan keeps every battery: the plan flown so far goes on)."""
        ctx, cause = self.ctx, self.trouble or ""
        self.trouble, self.urgent = None, False
        self.flights = {r: f for r, f in self.flights.items() if f.entry.status is not SortieStatus.LOST}
        # streamed battery readings are ~1 s of wall time old: many mission s on a fast simulated fleet
        await asyncio.gather(*(v.refresh_battery(BATTERY_READ_WAIT) for v in ctx.fleet.rovers.values()
                               if v.connected and not v.lost))
        problem, state = live_problem(ctx, self.board, self.changes.tasks, self.flights.values(),
                                      set(self.swaps.pending), self.carrier.pose())
        if not problem.tasks and not state.in_flight:
            return None
        try:
            plan = await asyncio.to_thread(plan_operation, problem, state, REPLAN_ROUNDS)
        except PlanningError as exc:
            ctx.state.event(Ev.REPLAN, f"replan after {cause} failed ({exc}); flying on with the plan", None,
                            cause=cause, error=str(exc))
            return None
        st = ctx.state
        st.replans += 1
        end = round(self.now() + plan.makespan, 3)
        text = (f"replan #{st.replans}: {cause} -> {len(problem.tasks)} tasks to launch, "
                f"{len(state.in_flight)} rovers in the air; ends at {end:.0f} s")
        if plan.recovery:
            text = (f"replan #{st.replans}: {cause} -> no plan keeps every reserve: recovery, the "
                    f"{len(state.in_flight)} rovers in the air come back (reserve given up) by {end:.0f} s; "
                    f"the {len(problem.tasks)} tasks left are planned once they are aboard")
        st.last_replan = text
        st.event(Ev.REPLAN, text, None, n=st.replans, cause=cause, makespan=end, recovery=plan.recovery)
        self._adopt(plan, f"plan-replan-{st.replans}.json")
        self._start_planned_swaps()
        return plan

    def _start_planned_swaps(self) -> None:
        """The swaps a new plan gives the rovers already on the deck (before their next launch)."""
        for rid, v in self.ctx.fleet.rovers.items():
            if rid not in self.flights and rid not in self.swaps.pending and not v.lost \
                    and rover_on_deck(self.ctx, v) and self._swap_due(rid, 0.0):
                self.swaps.start(rid)

    async def _start_route(self, plan: OperationPlan) -> list[tuple[int, int | None]]:
        ctx, c = self.ctx, self.carrier.vehicle
        if c.origin is None:
            raise ExecutionError("the mission has no origin: mission items need WGS84 coordinates")
        pose, _heading = self.carrier.pose()
        items, stops = route_items([s.position for s in plan.stops], c.origin, pose, c.autopilot)
        await upload(ctx, c, list(items))
        try:
            if not c.armed:
                await ctx.command(c, "arm", c.arm())
            await ctx.command(c, "start_mission", c.start_mission(0))
        except (CommandRejected, LinkError, TimeoutError) as exc:
            raise ExecutionError(f"the carrier {c.name} did not start its route: {exc}") from None
        if self.t0 is None:
            self.t0 = ctx.clock()
            self.result.started = self.t0
        else:  # a replan's route: the old route's current item must not count as the new one's arrival
            first = stops[0].arrive_seq
            with contextlib.suppress(TimeoutError):
                await ctx.wait_for(c, lambda v: first in v.items_reached or (
                    v.mission_current is not None and v.mission_current <= first), ROUTE_START_WAIT,
                    "the new route started")
        ctx.record(Ev.CARRIER_STARTED, stops=len(stops))
        return [(s.arrive_seq, s.release_seq) for s in stops]

    # ============================================================================== pick-ups
    async def _pick_up(self, k: int, seq: int, stop: OpStop, interruptible: bool) -> bool:
        """Wait for the stop's returning rovers, then for the carrier parked at the stop (its arrive
        item ``seq``: :meth:`CarrierControl.parked`; they hover meanwhile), land and load them;
        ``interruptible``: a rover short of battery in the air (:attr:`urgent`) ends the wait. True
        when rovers of the stop were left waiting for."""
        ctx = self.ctx
        flights = [self.flights[r] for r in stop.pickups if r in self.flights]
        for f in flights:
            if self._interrupt(interruptible):
                break
            try:
                await ctx.wait_for(f.vehicle, self._above_or_urgent(f, interruptible),
                                   ctx.late(f.pickup.meet + self.delay - self.now()), f"above stop {k + 1}")
            except TimeoutError as exc:
                f._lost(str(exc))
        left = [f for f in flights if f.entry.status is not SortieStatus.LOST and not f.above_stop(f.vehicle)]
        flights = [f for f in flights if f not in left]
        if any(f.entry.status is SortieStatus.RETURNING for f in flights):
            try:
                await self.carrier.parked(k, seq)
            except TimeoutError as exc:  # not sent down onto a carrier that is not there: they hover
                for f in flights:
                    if f.entry.status is SortieStatus.RETURNING:
                        f._lost(f"not landed: {exc}")
        def parked() -> Awaitable[None]:
            return self.carrier.parked(k, seq)

        landed = await asyncio.gather(*(land_on_deck(ctx, f, LANDING_TIMEOUT, seq, parked)
                                        for f in flights if f.entry.status is SortieStatus.RETURNING))
        if any(landed):
            await ctx.sleep_mission(ctx.mission.carrier.load_time)
            await asyncio.gather(*(f.vehicle.refresh_battery(BATTERY_READ_WAIT) for f in flights
                                   if not f.vehicle.lost))  # what they came back with
        for f in flights:
            self.flights.pop(f.entry.rover, None)
            if f.entry.status is SortieStatus.RETURNING and f.vehicle.on_ground:
                self._aboard(f, stop)
            elif f.entry.status is not SortieStatus.LOST:
                f._lost("did not land on the deck")
        return bool(left)

    def _aboard(self, f: SortieFlight, stop: OpStop) -> None:
        rid = f.entry.rover
        f.entry.status, f.entry.aboard = SortieStatus.ABOARD, self.now()
        self.ctx.state.set_state(rid, VehicleStatus.LOADED)
        self.ctx.state.event(Ev.SORTIE_BACK, f"{rid}: back on the deck from sortie {f.entry.index}", rid,
                             sortie=f.entry.index, battery_pct=f.vehicle.battery_pct)
        if self._swap_due(rid, f.pickup.aboard):
            self.swaps.start(rid)
        else:
            self._check_battery(f)

    def _check_battery(self, f: SortieFlight) -> None:
        """A rover back with less battery than planned flies its next sortie on it: replan when
        that sortie would take it below the reserve."""
        assert self.plan is not None
        frac, rid = f.vehicle.battery_fraction, f.entry.rover
        if frac is None or frac >= f.pickup.battery_left:
            return
        nxt = min((s for s in self.plan.sorties if s.rover == rid and s.takeoff > f.pickup.aboard),
                  key=lambda s: s.takeoff, default=None)
        reserve = self.ctx.mission.rovers.reserve
        if nxt is not None and nxt.battery_left - (f.pickup.battery_left - frac) < reserve + BATTERY_SLACK:
            self._on_trouble(f"rover {rid} back with {100 * frac:.0f} % of its battery, "
                             f"{100 * f.pickup.battery_left:.0f} % planned: too little for its next sortie")

    def _swap_due(self, rover: str, aboard: float) -> bool:
        """A planned swap of ``rover`` after this pick-up and before its next launch."""
        assert self.plan is not None
        nxt = min((s.takeoff for s in self.plan.sorties if s.rover == rover and s.takeoff > aboard),
                  default=None)
        return nxt is not None and any(w.rover == rover and aboard - SWAP_EPS <= w.start < nxt
                                       for w in self.plan.swaps)

    # ============================================================================== launches
    async def _launch(self, k: int, stop: OpStop) -> None:
        assert self.plan is not None
        sorties = [(i, s) for i, s in enumerate(self.plan.sorties)
                   if s.launch_stop == k and i in self.entry_of]
        if not sorties:
            return
        go_at = self.ctx.clock() + self.ctx.mission.carrier.unload_time
        await asyncio.gather(*(self._launch_one(i, s, stop, go_at) for i, s in sorties))

    async def _launch_one(self, i: int, s: Sortie, stop: OpStop, go_at: float) -> None:
        ctx, plan = self.ctx, self.plan
        assert plan is not None
        entry = self.entry_of[i]
        if not await self.swaps.ready(s.rover, ctx.late(ctx.mission.carrier.swap_time)):
            entry.status = SortieStatus.FAILED
            return
        v = ctx.fleet.rovers[s.rover]
        if v.origin is None:
            raise ExecutionError("the mission has no origin: mission items need WGS84 coordinates")
        visits = [Visit(x.task, x.position, self.board.tasks[x.task].duration, x.ground) for x in s.visits
                  if x.task in self.board.tasks]  # a task removed since (a replan that found no plan)
        if not visits:
            entry.status = SortieStatus.FAILED
            return
        items = sortie_items(s.rover, stop.position, visits, v.origin, v.autopilot)
        slot = RoverMission(s.rover, s.launch_stop, items.items, items.work[0].arrive_seq,
                            len(items.items) - 1, items.work[0].task)
        launcher = Launcher(ctx, self.carrier, TaskBoard.of([]))
        rid = await launcher.launch(slot, entry.index, Spares([]), go_at)
        if rid is None:
            entry.status = SortieStatus.FAILED
            ctx.state.event(Ev.ROVER_FAILED, f"{s.rover}: sortie {entry.index} did not take off", s.rover,
                            sortie=entry.index)
            self._on_trouble(f"rover {s.rover} did not take off")
            return
        entry.status, entry.launched = SortieStatus.FLYING, self.now()
        ctx.state.set_state(rid, VehicleStatus.EN_ROUTE, entry.tasks[0])
        ctx.state.event(Ev.SORTIE_LAUNCHED,
                        f"{rid}: sortie {entry.index} launched for {', '.join(entry.tasks)}", rid,
                        sortie=entry.index, tasks=entry.tasks, stop=s.launch_stop + 1,
                        work=[[w.task, w.arrive_seq, w.done_seq] for w in items.work])
        flight = SortieFlight(ctx, self.board, entry, s, items, self._pickup(plan, s),
                              FlightClock(self.base, self.now, lambda: self.delay), self._on_trouble)
        flight.low_battery = self._on_low_battery
        self.flights[rid] = flight
        ctx.spawn(flight.fly(), f"sortie {entry.index} {rid}")

    # ============================================================================== the end
    def _finish(self) -> PhaseResult:
        r, b = self.snapshot(), self.board
        how = "complete" if r.complete else "incomplete"
        swaps = f"{len(b.swaps)} swap{'' if len(b.swaps) == 1 else 's'}"
        text = (f"operation {how}: {len(r.tasks_done)}/{len(b.tasks)} tasks done, {swaps}, "
                f"{r.flown or 0.0:.1f} s (planned {r.planned or 0.0:.1f} s)")
        self.ctx.state.event(Ev.OPERATION_DONE, text, None, complete=r.complete, tasks_done=len(r.tasks_done),
                             flown=r.flown)
        return r

    def snapshot(self) -> PhaseResult:
        """What the operation achieved so far (also after an interruption or failure)."""
        r, b, ctx = self.result, self.board, self.ctx
        r.flown = round(self.now(), 3)
        r.tasks_reached = [t for t, w in b.tasks.items() if w.started is not None]
        r.tasks_done = b.done()
        r.tasks_unserved = b.left()
        r.unserved_reasons = {t: "its work was not done" for t in b.left()}
        r.tasks_all = list(b.tasks)
        r.tasks_added, r.tasks_removed = list(self.changes.added), list(self.changes.removed)
        r.rovers_lost = list(b.lost)
        aboard = {s.rover for s in b.sorties if s.status is SortieStatus.ABOARD}
        r.rovers_loaded = [rid for rid in ctx.fleet.rovers if rid in aboard]
        r.launched = sorted({s.rover for s in b.sorties if s.launched is not None})
        r.assignment = {t: w.rover for t, w in b.tasks.items() if w.rover is not None}
        r.complete = not b.left() and not any(
            s.status in (SortieStatus.FLYING, SortieStatus.RETURNING) for s in b.sorties)
        return r


__all__ = ["OperationPhase"]
