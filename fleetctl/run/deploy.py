"""The deployment phase: plan from the live state, fly stop by stop, replan on events.

State lives on the :class:`~fleetctl.run.task_board.TaskBoard`. The phase is a replan loop:
each round plans the pooled tasks from the carrier's live pose with the rovers still usable on
its deck, uploads and starts the carrier's route, and flies it (:meth:`DeployPhase._fly`): at
each stop it launches that stop's rovers (:class:`~fleetctl.run.launch.Launcher`), waits the
unload time and releases the carrier. A supervision event that throws the rest of the route
away (a rover lost in flight, tasks changed, a rover landed at its reserve while the carrier was
lost) ends the round where the carrier is, and the next round replans from there (Fig. 4.14).

A task is *reached* when its rover holds within :data:`REACH_RADIUS` of it (:meth:`_watch`).
"""

from __future__ import annotations

import asyncio
import dataclasses
import math
from dataclasses import dataclass

from fleetctl.mavlink.compile import CompiledPlan, RoverMission
from fleetctl.mavlink.link import LinkError
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle
from fleetctl.run.context import ExecutionError, RunContext
from fleetctl.run.events import announce_warning, drain, next_event, race
from fleetctl.run.kinds import Ev, Phase, VehicleStatus, Watch
from fleetctl.run.launch import DECK_CHECK_TIMEOUT, Launcher, Spares, flight_path, rover_on_deck, takeoff_seq
from fleetctl.run.parts import PhaseParts
from fleetctl.run.preflight import planning_range
from fleetctl.run.results import PhaseResult
from fleetctl.run.supervisor import SupervisorEvent, validate_task_change
from fleetctl.run.task_board import TaskBoard
from fleetctl.run.trouble import HOLD_SPEED, Trouble
from planners.core.plan import Plan, RoverLeg
from planners.core.problem import Task, Vec3
from planners.core.ranges import leg_length


@dataclass(frozen=True)
class ResumedDeploy:
    """What ``fleetctl resume`` knows of an interrupted deployment (the board holds the rest)."""

    elapsed: float  # mission seconds since the carrier first started
    planned: float | None  # the first plan's makespan


REACH_RADIUS = 1.0  # m: a rover within this 3D distance of its task, holding, has reached it
WATCH_RETRIES = 3  # timeouts of a task watch forgiven while the carrier's link was down


class DeployPhase:
    """One deployment (see the module docstring)."""

    def __init__(
        self,
        parts: PhaseParts,
        board: TaskBoard,
        resumed: ResumedDeploy | None = None,
    ) -> None:
        self.ctx, self.carrier = parts.ctx, parts.carrier
        self.supervisor, self.planning = parts.supervisor, parts.planning
        self.board = board
        self.launcher = Launcher(parts.ctx, parts.carrier, board)
        self.watchers: dict[str, asyncio.Task[None]] = {}  # task -> the watch of its rover
        self.grace: dict[str, asyncio.Task[None]] = {}  # lost flying rover -> its reassign timer
        self.deck: list[str] = []  # rovers on the deck when the phase began
        self.plan: Plan | None = None
        self.t0: float | None = None  # mission clock when the carrier first started
        self.result = PhaseResult("deploy")
        self.resumed = resumed

    # ============================================================================== the loop
    async def run(self) -> PhaseResult:
        """Plan and fly until every task is reached or unserved; returns the result."""
        ctx = self.ctx
        ctx.state.set_phase(Phase.PLAN)
        await ctx.wait_telemetry()
        self.supervisor.start()
        await self._check_deck()
        if self.resumed is not None:
            self._adopt(self.resumed)
        q = self.supervisor.queue
        while True:
            drain(q, self.handle)
            tasks, usable = self._next_round()
            if tasks:
                await self._round(tasks, usable)
                continue
            ctx.replans.ready(None)
            pending = {w for w in self.watchers.values() if not w.done()}
            if not pending:
                break
            ev = await next_event(q, pending, ctx.wall(60.0))
            if ev is not None:
                self.handle(ev)
        return self._finish()

    async def _check_deck(self) -> None:
        """Which rovers are on the deck (waiting briefly for landed states under packet loss)."""
        ctx, board = self.ctx, self.board
        rovers = ctx.fleet.rovers
        deck = [rid for rid, v in rovers.items() if rover_on_deck(ctx, v)]
        if len(deck) < len(board.pooled()):
            await asyncio.gather(
                *(
                    _settle(ctx, v)
                    for rid, v in rovers.items()
                    if rid not in deck and v.connected and not v.lost
                )
            )
            deck = [rid for rid, v in rovers.items() if rover_on_deck(ctx, v)]
        flying = set(board.airborne())
        for rid, v in rovers.items():
            if rid in flying:
                continue
            away = VehicleStatus.LOST if not v.connected or v.lost else VehicleStatus.LANDED
            ctx.state.set_state(rid, VehicleStatus.ON_DECK if rid in deck else away)
        self.deck = deck
        usable = [rid for rid in deck if board.available(rid)]
        if len(usable) < len(board.pooled()) and self.resumed is None:
            raise ExecutionError(
                f"{len(usable)} rover(s) on the carrier's deck ({', '.join(usable) or 'none'}) "
                f"for {len(board.pooled())} tasks: every task needs a rover on the deck"
            )

    def _adopt(self, resumed: ResumedDeploy) -> None:
        """Take over an interrupted deployment: its clock, its planned makespan and a watch on
        every rover still flying to its task."""
        ctx, st = self.ctx, self.ctx.state
        now = ctx.clock()
        self.t0 = self.result.started = now - resumed.elapsed
        self.result.planned = resumed.planned
        st.set_phase(Phase.DEPLOY, resumed.planned, 0)
        st.phase_started = self.t0
        speed = ctx.mission.rovers.max_speed
        for task, rid in self.board.flying().items():
            target = self.board.entries[task].task.position
            pos = ctx.fleet.rovers[rid].enu
            eta = (math.dist(pos, target) / speed if pos is not None else 0.0) + 10.0
            st.set_state(rid, VehicleStatus.EN_ROUTE, task=task)
            self.supervisor.expect(rid, [pos, target] if pos is not None else None)
            self.watch(rid, task, target, eta, now)
            v = ctx.fleet.rovers[rid]
            if v.mode != "MISSION":  # held when the controller went down: fly on to its task
                ctx.spawn(self._continue(v), f"continue {rid}")

    async def _continue(self, v: Vehicle) -> None:
        try:
            await self.ctx.command(v, "continue_mission", v.set_mode("MISSION"))
        except (CommandRejected, LinkError, TimeoutError) as exc:
            self.ctx.state.event(Ev.ROVER_FAILED, f"{v.name}: could not continue its mission ({exc})", v.name)

    def _next_round(self) -> tuple[list[Task], list[str]]:
        """The pooled tasks the next round plans, and the usable rovers on the deck; tasks beyond
        the rovers left are unserved."""
        board, rovers = self.board, self.ctx.fleet.rovers
        usable = [rid for rid in self.deck if board.available(rid) and not rovers[rid].lost]
        tasks = board.pooled()
        for t in tasks[len(usable) :]:
            board.unserve(t.id, "no spare rover left on the deck")
            self.ctx.state.event(
                Ev.TASK_UNSERVED, f"{t.id}: no spare rover left on the deck", None, task=t.id
            )
        return tasks[: len(usable)], usable

    async def _round(self, tasks: list[Task], usable: list[str]) -> None:
        """Plan ``tasks`` from where the carrier is, start its route and fly it."""
        ctx, st = self.ctx, self.ctx.state
        await self.carrier.ready()
        start, heading = self.carrier.pose()
        problem = dataclasses.replace(
            ctx.mission.deploy_problem(),
            start=start,
            heading=heading,
            tasks=tuple(tasks),
            rovers=tuple(usable),
            rover_ranges=tuple(self._ranges(usable).items()),
        )
        plan = await self.planning.plan("deploy", problem)
        compiled = self.planning.compile(plan)
        ctx.replans.ready(plan)
        if self.t0 is None:
            self.result.plan, self.result.planned = plan, plan.makespan
            st.set_phase(Phase.DEPLOY, plan.makespan, len(plan.stops))
            await asyncio.gather(
                *(self.launcher.pre_upload(s, id(compiled)) for s in compiled.rovers.values())
            )
        else:
            st.planned = (ctx.clock() - self.t0) + plan.makespan
            st.stop_count, st.stop_index = len(plan.stops), 0
        await self.carrier.start_route(compiled)
        plan_t0 = st.plan_started = ctx.clock()
        if self.t0 is None:
            self.t0 = self.result.started = st.phase_started = plan_t0
            cid = ctx.fleet.carrier_id
            st.event(Ev.CARRIER_STARTED, f"{cid}: route started ({len(plan.stops)} stops)", cid)
        self.plan = plan
        await self._fly(plan, compiled, usable, plan_t0)

    def _ranges(self, rovers: list[str]) -> dict[str, float]:
        """The rovers whose battery (now) cannot fly the deploy range -> the range it can: they
        are planned with it (fleetctl.run.preflight.planning_range, planners.core.ranges)."""
        full = self.ctx.mission.rovers.deploy_range
        out = {}
        for rid in rovers:
            rng = planning_range(self.ctx.fleet.rovers[rid], self.ctx.mission)
            if rng is not None and rng < full:
                out[rid] = rng
        return out

    # ============================================================================== one route
    async def _fly(self, plan: Plan, compiled: CompiledPlan, usable: list[str], plan_t0: float) -> None:
        """Fly the stops of one plan; returns early when an event asks for a replan (the carrier
        holds at the stop it is at)."""
        ctx, board = self.ctx, self.board
        slots = compiled.rovers  # planned rover id -> its mission (the rover flying it may differ)
        spares = Spares([rid for rid in usable if rid not in slots], used=set(slots),
                        ranges=self._ranges(usable),
                        needs={leg.rover: leg_length(leg) for leg in plan.legs() if leg.task is not None})
        ctx.record(Ev.SPARES, rovers=spares.rovers)
        q = self.supervisor.queue
        last = len(plan.stops) - 1
        prev = 0.0
        for k, (stop, items) in enumerate(zip(plan.stops, compiled.stops, strict=True)):
            ok, arrived = await race(q, self._arrive(k, items.arrive_seq, stop.arrive - prev), self.handle)
            if not ok or arrived is None:
                return  # the rest of the route is thrown away
            prev = stop.depart
            self._predict(plan, k, arrived - plan_t0)
            at = (stop.position[0], stop.position[1], 0.0)
            unloaded = arrived + ctx.mission.carrier.unload_time  # the rovers leave the deck then
            launches = [
                self._launch(slots[leg.rover], leg, at, id(compiled), spares, plan_t0, unloaded)
                for leg in stop.rovers
                if leg.task is not None and board.is_pooled(leg.task)
            ]
            unload = ctx.sleep_mission(max(unloaded - ctx.clock(), 0.0))
            await asyncio.gather(unload, *launches)
            if drain(q, self.handle) and k < last or board.pooled() and k == last:
                return  # replan from this stop (the carrier holds here)
            await self.carrier.release(k, items.release_seq)

    async def _arrive(self, k: int, seq: int, planned_leg: float) -> float:
        """Wait for the carrier at stop ``k`` (its arrive item ``seq``), standing: the rovers leave
        a deck that does not move. Returns when it reached the stop (mission clock). A carrier that
        reaches its item still driving is waited for (:meth:`CarrierControl.parked`) and, where its
        firmware does not stand it still (:attr:`CarrierControl.stands_disarmed`), held disarmed
        as soon as it stands: PX4 1.18's Ackermann carrier passed its stop item at 1 m/s and wandered
        up to 1.2 m about it for up to 7 s, while its rovers took off from the deck (one was held
        on it for 5 s, its velocity estimate swinging)."""
        arrived = await self.carrier.reach_stop(k, seq, planned_leg)
        if not self.carrier.is_parked(seq):
            try:
                await self.carrier.parked(k, seq, hold=self.carrier.stands_disarmed)
            except TimeoutError as exc:
                raise ExecutionError(f"the carrier did not stand on stop {k + 1}: {exc}") from None
        return arrived

    def _predict(self, plan: Plan, k: int, arrived: float) -> None:
        """The live makespan prediction once the carrier is at stop ``k``: the plan shifted by
        how late (or early) it got there (the rest of the route keeps its planned times)."""
        st = self.ctx.state
        if st.planned is not None:
            st.eta = st.planned + (arrived - plan.stops[k].arrive)
            self.ctx.record(Ev.ETA, phase="deploy", stop=k + 1, eta=st.eta)

    async def _launch(
        self, slot: RoverMission, leg: RoverLeg, at: Vec3, plan_id: int, spares: Spares, plan_t0: float,
        go_at: float,
    ) -> None:
        ctx, board, st = self.ctx, self.board, self.ctx.state
        task = slot.task or ""
        rid = await self.launcher.launch(slot, plan_id, spares, go_at)
        if rid is None:
            if board.is_pooled(task):
                board.unserve(task, "no rover left on the deck to fly it (every spare used, lost or refused)")
                st.event(Ev.TASK_UNSERVED, f"{task}: no rover left to fly it", None, task=task)
            return
        if task not in board.entries:  # removed while it was being launched
            board.launched.append(rid)
            board.rejoined.append(rid)
            st.set_state(rid, VehicleStatus.ON_TASK)
            return
        board.fly(task, rid)
        st.set_state(rid, VehicleStatus.CLIMBING, task=task)
        st.event(
            Ev.ROVER_LAUNCHED,
            f"{rid}: launched for {task} at stop {slot.stop + 1}",
            rid,
            task=task,
            stop=slot.stop + 1,
        )
        self.supervisor.expect(rid, flight_path(ctx, slot, at))
        self.watch(rid, task, leg.end, leg.arrive, plan_t0, takeoff_seq(slot), slot.target_seq)

    # ============================================================================== task watch
    def watch(
        self, rid: str, task: str, target: Vec3, arrive: float, plan_t0: float, takeoff: int = -1,
        target_seq: int = -1,
    ) -> None:
        """Watch ``rid`` until it holds at ``task`` (planned to arrive ``arrive`` s after
        ``plan_t0``): its position there, or its autopilot reporting the task's item reached
        (``target_seq``; at once, where positions come at the telemetry rate)."""
        self.watchers[task] = self.ctx.spawn(
            self._watch(rid, task, target, arrive, plan_t0, takeoff, target_seq), f"watch {rid}"
        )

    async def _watch(
        self, rid: str, task: str, target: Vec3, arrive: float, plan_t0: float, takeoff: int,
        target_seq: int,
    ) -> None:
        ctx, st = self.ctx, self.ctx.state
        v = ctx.fleet.rovers[rid]

        trouble = Trouble(lambda: (target,))

        def check(v: Vehicle) -> bool:
            if st.vehicles[rid].state == VehicleStatus.CLIMBING and (v.mission_current or 0) > takeoff:
                st.set_state(rid, VehicleStatus.EN_ROUTE)
            p = v.enu
            if trouble.seen(v):
                return True
            if target_seq >= 0 and target_seq in v.items_reached:
                return True
            return (
                p is not None
                and math.dist(p, target) <= REACH_RADIUS
                and (v.ground_speed or 0.0) < HOLD_SPEED
            )

        tries = 0
        while True:
            losses = self.carrier.losses
            remaining = max(arrive - (ctx.clock() - plan_t0), 0.0)
            try:
                await ctx.wait_for(v, check, ctx.late(remaining), f"task {task}")
                break
            except TimeoutError:
                tries += 1
                if (losses == self.carrier.losses and not self.carrier.lost) or tries > WATCH_RETRIES:
                    self.board.unserve(task, f"{rid} did not reach it in time")
                    st.event(Ev.TASK_TIMEOUT, f"{rid}: did not reach {task} in time", rid, task=task)
                    return
        self.watchers.pop(task, None)
        self.supervisor.expect(rid, None)
        if trouble.why is not None:  # it will not get there: hand the task back at once
            self.supervisor.put(SupervisorEvent(Watch.STRANDED, rid, data={"task": task, "why": trouble.why}))
            return
        flown = ctx.clock() - (self.t0 if self.t0 is not None else plan_t0)
        self.board.reach(task, flown)
        st.set_state(rid, VehicleStatus.ON_TASK)
        st.event(
            Ev.TASK_REACHED,
            f"{rid}: reached {task} (at {flown:.1f} s, planned {arrive:.1f} s of its plan)",
            rid,
            task=task,
            flown=flown,
            planned=arrive,
        )

    def _stop_watching(self, task: str, rid: str) -> None:
        w = self.watchers.pop(task, None)
        if w is not None:
            w.cancel()
        self.supervisor.expect(rid, None)

    # ============================================================================== events
    def handle(self, ev: SupervisorEvent) -> bool:
        """Apply one supervision event to the board; True when the rest of the route must be
        replanned."""
        rid = ev.vehicle
        if ev.kind in (Watch.LOST, Watch.BACK) and rid == self.ctx.fleet.carrier_id:
            return self._on_carrier_link(ev)
        if ev.kind == Watch.LOST and rid is not None:
            return self._on_rover_lost(ev, rid)
        if ev.kind == Watch.BACK and rid is not None:
            return self._on_rover_back(ev, rid)
        if ev.kind == Watch.TASKS:
            return self._on_tasks(ev)
        if ev.kind == Watch.REASSIGN and rid is not None:
            return self._on_reassign(ev, rid)
        if ev.kind == Watch.STRANDED and rid is not None:
            return self._on_stranded(ev, rid)
        announce_warning(self.ctx, ev)
        return False

    def _on_carrier_link(self, ev: SupervisorEvent) -> bool:
        landing = self.carrier.on_link(ev, self.board.airborne)
        landed = [(t, r) for t, r in self.board.flying().items() if r in landing]
        for task, r in landed:  # it will not reach its task: the task goes back to the pool
            self._stop_watching(task, r)
            self.board.give_back(
                task, f"its rover {r} landed at the battery reserve while the carrier was lost"
            )
            self.board.rejoined.append(r)  # a rover to collect where it landed
            self.ctx.state.event(
                Ev.TASK_RETURNED,
                f"{task}: {r} landed at the battery reserve; the task goes back to the pool",
                r,
                task=task,
            )
        if landed:
            self.ctx.replans.begin(
                f"{', '.join(r for _, r in landed)} landed at the battery reserve (carrier lost)",
                ev,
                self.plan,
            )
        return bool(landed)

    def _on_rover_lost(self, ev: SupervisorEvent, rid: str) -> bool:
        st = self.ctx.state
        st.set_state(rid, VehicleStatus.LOST)
        task = self.board.task_of(rid)
        if task is not None:
            after = self.ctx.mission.links.reassign_after
            if after <= 0:
                return self._give_back(ev, rid, task, f"its rover {rid} was lost in flight", "lost in flight")
            # its autopilot flies on: the task stays with it for a while (a flapping link comes back)
            self.ctx.record(Ev.REASSIGN_PENDING, vehicle=rid, task=task, after=after)
            self.grace[rid] = self.ctx.spawn(self._reassign_later(rid, task, after), f"grace {rid}")
            return False
        if rid not in self.board.launched:
            self.board.unusable.add(rid)
            st.event(Ev.ROVER_UNUSABLE, f"{rid}: lost on the deck: unusable, a spare takes its place", rid)
        return False

    async def _reassign_later(self, rid: str, task: str, after: float) -> None:
        await self.ctx.sleep_mission(after)  # mission seconds, like the heartbeat timeout
        self.grace.pop(rid, None)
        self.supervisor.put(SupervisorEvent(Watch.REASSIGN, rid, data={"task": task, "after": after}))

    def _on_reassign(self, ev: SupervisorEvent, rid: str) -> bool:
        task = ev.data.get("task")
        v = self.ctx.fleet.rovers[rid]
        if not v.lost or not isinstance(task, str) or self.board.task_of(rid) != task:
            return False  # back in time, or the task moved on
        after = ev.data.get("after")
        return self._give_back(ev, rid, task, f"its rover {rid} was lost in flight for more than {after:g} s",
                               f"lost in flight for {after:g} s")

    def _on_stranded(self, ev: SupervisorEvent, rid: str) -> bool:
        task = ev.data.get("task")
        if not isinstance(task, str) or self.board.task_of(rid) != task:
            return False
        why = str(ev.data.get("why"))
        self.board.rejoined.append(rid)  # a rover to collect where it is
        return self._give_back(ev, rid, task, f"its rover {rid} {why}", why)

    def _give_back(self, ev: SupervisorEvent, rid: str, task: str, reason: str, short: str) -> bool:
        """``rid`` will not reach ``task``: the task goes back to the pool and the route is replanned."""
        self._stop_watching(task, rid)
        self.board.give_back(task, reason)
        self.ctx.state.event(Ev.TASK_RETURNED, f"{task}: {rid} {short}; the task goes back to the pool", rid,
                             task=task)
        self.ctx.replans.begin(f"{rid} {short} (task {task})", ev, self.plan)
        return True

    def _on_rover_back(self, ev: SupervisorEvent, rid: str) -> bool:
        st, board = self.ctx.state, self.board
        grace = self.grace.pop(rid, None)
        if grace is not None:  # back within links.reassign_after: nothing changes
            grace.cancel()
            task = board.task_of(rid)
            st.set_state(rid, VehicleStatus.EN_ROUTE, task=task)
            st.event(Ev.ROVER_REJOINED, f"{rid}: link back in time: keeps {task}", rid, task=task)
            return False
        if rid in board.unusable:
            board.unusable.discard(rid)
            st.set_state(rid, VehicleStatus.ON_DECK)
            st.event(Ev.ROVER_REJOINED, f"{rid}: back on the deck: a spare again", rid)
            starved = board.repool_unserved()
            if starved:
                self.ctx.replans.begin(f"{rid} back on the deck (for {', '.join(starved)})", ev, self.plan)
                return True
        elif rid in board.launched:
            on = board.task_of(rid) is not None
            st.set_state(rid, st.vehicles[rid].state if on else VehicleStatus.ON_TASK)
            if not on:
                board.rejoined.append(rid)
            st.event(
                Ev.ROVER_REJOINED,
                f"{rid}: link back" + ("" if on else ": rejoins as a rover to collect"),
                rid,
            )
        return False

    def _on_tasks(self, ev: SupervisorEvent) -> bool:
        ctx, board = self.ctx, self.board
        why = validate_task_change(board.tasks, ev.add, ev.remove, ctx.mission.rovers.deploy_range)
        rovers = ctx.fleet.rovers
        free = sum(1 for r in self.deck if board.available(r) and not rovers[r].lost)
        pooled = {t.id for t in board.pooled()}
        need = len(pooled) + len(ev.add) - sum(1 for r in ev.remove if r in pooled)
        if why is None and need > free:
            why = f"{need} tasks to fly but only {free} rover(s) left on the deck"
        if why is not None:
            self.supervisor.reject(why, ev.source)
            return False
        again = bool(ev.add)
        for tid in ev.remove:
            again = tid in pooled or again
            r = board.remove(tid)
            if r is not None:
                self._stop_watching(tid, r)
                board.rejoined.append(r)
                ctx.state.event(
                    Ev.ROVER_RELEASED,
                    f"{r}: its task {tid} was removed; it holds there to be collected",
                    r,
                    task=tid,
                )
        for t in ev.add:
            board.add(t)
        ctx.state.event(
            Ev.TASKS_CHANGED,
            f"tasks changed ({ev.source}): added "
            f"{', '.join(t.id for t in ev.add) or 'none'}, removed {', '.join(ev.remove) or 'none'}",
            None,
            add=[t.id for t in ev.add],
            remove=list(ev.remove),
            source=ev.source,
            added=[{"id": t.id, "position": list(t.position)} for t in ev.add],
        )
        if again:
            ctx.replans.begin(f"tasks changed ({ev.source}): +{len(ev.add)} -{len(ev.remove)}", ev, self.plan)
        return again

    # ============================================================================== the result
    def _finish(self) -> PhaseResult:
        self.ctx.state.set_state(self.ctx.fleet.carrier_id, VehicleStatus.IDLE)
        return self.snapshot()

    def snapshot(self) -> PhaseResult:
        """The result as the board has it now (also after an interruption)."""
        ctx, board, res = self.ctx, self.board, self.result
        order = list(board.entries)
        reached = board.reached()
        res.tasks_reached = [t for t in order if t in reached]
        res.tasks_unserved = [t for t in order if t not in reached]
        reasons = board.unserved_reasons()
        res.unserved_reasons = {t: reasons.get(t, "not reached") for t in res.tasks_unserved}
        res.tasks_all = order
        res.launched = list(board.launched)
        res.assignment = dict(board.assignment)
        res.substitutions = list(board.substitutions)
        res.tasks_added, res.tasks_removed = list(board.added), list(board.removed)
        res.rejoined = list(board.rejoined)
        res.airborne = board.airborne()
        res.rovers_lost = [rid for rid, v in ctx.fleet.rovers.items() if v.lost]
        res.complete = not res.tasks_unserved
        if res.complete:
            res.flown = max(reached.values()) if reached else 0.0
        return res


async def _settle(ctx: RunContext, v: Vehicle) -> None:
    try:
        await v.wait_until(lambda v: rover_on_deck(ctx, v), DECK_CHECK_TIMEOUT, "on the deck")
    except TimeoutError:
        pass


__all__ = ["HOLD_SPEED", "REACH_RADIUS", "DeployPhase", "ResumedDeploy"]
