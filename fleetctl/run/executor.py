"""Execution state machines: fly a deployment and a collection over MAVLink.

:class:`Executor` works on a connected :class:`fleetctl.mavlink.vehicle.Fleet` and writes what happens
into a :class:`fleetctl.fleet.FleetState` (read by the dashboard) and the journal.

Deployment: plan with the mission's planner from the carrier's live position and heading, upload
the carrier's route (:mod:`fleetctl.mavlink.compile`: a waypoint and an unlimited loiter per stop) and the
rovers' missions (take-off to task height, waypoint(s) to the task, loiter), start the carrier,
then stop by stop: wait for the carrier to arrive, launch that stop's rovers (any rover on the
deck may take any task; one that refuses to arm is skipped and a spare takes its task), wait
until they are off the deck and ``unload_time`` has passed, release the carrier. A task is
*reached* when its rover holds within :data:`REACH_RADIUS` of it.

Collection: read every rover's position and battery, derive ranges (:mod:`fleetctl.run.energy`),
plan (``planners.COLLECT_PLANNERS``), send each rover above its meeting point (where it holds in
an unlimited loiter) and the carrier along its route; when the carrier is at a stop, the stop's
rovers are released to land on it; the carrier waits until every one of them is *loaded* (landed
within :data:`fleetctl.fleet.DECK_RADIUS` of it), then ``load_time``, then continues.

Times: ``clock`` is the mission clock (simulated seconds on the embedded simulator, else
``time.monotonic``); ``speedup`` converts mission seconds into wall seconds for timeouts. Every
wait has a timeout derived from the plan.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import math
import time
from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.mavlink.compile import (
    CompiledPlan,
    CompileError,
    RoverMission,
    StopItems,
    compile_for_fleet,
    item_position,
)
from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.link import LinkError, MissionItem, MissionRejected
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle, VehicleEvent
from fleetctl.mission import Mission
from fleetctl.run import state as fs
from fleetctl.run.energy import range_from_percent
from fleetctl.run.state import FleetState, on_deck
from fleetctl.run.supervisor import Supervisor, SupervisorEvent, validate_task_change
from planners.plan import Plan, RoverLeg, Stop
from planners.problem import CollectProblem, CollectRover, PlanningError, Task, Vec3

log = logging.getLogger(__name__)

M = mavlink2
T = TypeVar("T")

REACH_RADIUS = 1.0  # m: a rover within this 3D distance of its task, holding, has reached it
HOLD_SPEED = 0.3  # m/s: slower than this counts as holding
AIRBORNE_HEIGHT = 0.3  # m above home: a launched rover is off the deck
COLLECT_MEET_HEIGHT = 3.0  # m above the carrier's stop where a returning rover waits for the carrier
TELEMETRY_TIMEOUT = 10.0  # wall s to wait for first positions
DECK_CHECK_TIMEOUT = 2.0  # wall s for fresh telemetry to show a rover on the (stopped) carrier's deck
TIMEOUT_FACTOR = 2.0  # a wait may take this many times its planned (mission) duration ...
TIMEOUT_MARGIN = 30.0  # ... plus this many mission seconds ...
TIMEOUT_WALL = 15.0  # ... plus this many wall seconds (protocol retries, packet loss)
CARRIER_OUTAGE_MAX = 600.0  # mission s the controller waits for a lost carrier to come back


class ExecutionError(Exception):
    """The mission cannot be flown (a rejected upload, no rovers on the deck, ...): the message
    says what happened and what to change."""


@dataclass
class PhaseResult:
    kind: str  # "deploy" | "collect"
    plan: Plan | None = None
    complete: bool = False
    planned: float | None = None  # planned makespan (mission seconds)
    flown: float | None = None  # flown makespan (mission seconds), None when not complete
    started: float | None = None  # mission clock when the carrier started
    tasks_reached: list[str] = field(default_factory=list)
    tasks_unserved: list[str] = field(default_factory=list)
    rovers_loaded: list[str] = field(default_factory=list)
    rovers_lost: list[str] = field(default_factory=list)
    rovers_unreachable: list[str] = field(default_factory=list)  # collect: too little range to be picked up
    assignment: dict[str, str] = field(default_factory=dict)  # task -> rover (deploy)
    substitutions: list[dict[str, str]] = field(default_factory=list)  # refused rover -> spare
    error: str | None = None
    unserved_reasons: dict[str, str] = field(default_factory=dict)  # deploy: task -> why not reached
    tasks_all: list[str] = field(default_factory=list)  # deploy: the live task set at the end
    tasks_added: list[str] = field(default_factory=list)
    tasks_removed: list[str] = field(default_factory=list)
    launched: list[str] = field(default_factory=list)  # deploy: rovers that left the deck
    rejoined: list[str] = field(default_factory=list)  # deploy: rovers in the field without a task


class Executor:
    """Flies a mission's deployment and collection on a connected fleet."""

    def __init__(self, mission: Mission, fleet: Fleet, state: FleetState, *,
                 record: Callable[..., None] | None = None, planner: str | None = None,
                 speedup: float = 1.0, clock: Callable[[], float] | None = None,
                 write_plan: Callable[[str, Plan], None] | None = None) -> None:
        self.mission = mission
        self.fleet = fleet
        self.state = state
        self.record = record or (lambda kind, **data: None)
        self.planner = planner
        self.speedup = speedup
        self.clock = clock or time.monotonic
        self.write_plan = write_plan
        self.refused: set[str] = set()
        self._tasks: set[asyncio.Task[Any]] = set()
        self._unlisten = fleet.add_listener(self._on_vehicle_event)
        state.mission_clock = self.clock
        self.tasks: dict[str, Task] = {t.id: t for t in mission.tasks}  # the live task set
        self.supervisor = Supervisor(mission, fleet, state, tasks=lambda: dict(self.tasks),
                                     record=self.record)
        try:
            self._loop: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
        except RuntimeError:
            self._loop = None
        self._replan: dict[str, Any] | None = None  # the replan whose first command is not sent yet
        self._carrier_ok = asyncio.Event()
        self._carrier_ok.set()
        self._carrier_losses = 0
        self._held: set[str] = set()  # rovers paused while the carrier is lost

    # -- plumbing ----------------------------------------------------------------------------------
    def _on_vehicle_event(self, ev: VehicleEvent) -> None:
        if ev.kind == "lost":
            self.state.set_state(ev.vehicle, fs.LOST)
            self.state.event("link_lost", f"{ev.vehicle}: link lost (no heartbeat for "
                             f"{ev.data.get('timeout', 0):g} s)", ev.vehicle)
        elif ev.kind == "back":
            self.state.event("link_back", f"{ev.vehicle}: link back", ev.vehicle)
        elif ev.kind == "statustext":
            self.record("statustext", vehicle=ev.vehicle, text=ev.data.get("text"),
                        severity=ev.data.get("severity"))
        elif ev.kind in ("armed", "disarmed", "mode", "landed_state"):
            self.record(ev.kind, vehicle=ev.vehicle, **ev.data)

    def _spawn(self, coro: Awaitable[T], name: str) -> asyncio.Task[T]:
        task = asyncio.ensure_future(coro)
        task.set_name(name)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    async def close(self) -> None:
        """Cancel every background task (call on shutdown)."""
        self._unlisten()
        await self.supervisor.close()
        tasks = list(self._tasks)
        for t in tasks:
            t.cancel()
        for t in tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await t

    def wall(self, mission_seconds: float) -> float:
        """Wall seconds a wait of ``mission_seconds`` may take (generous: see TIMEOUT_*)."""
        return (mission_seconds * TIMEOUT_FACTOR + TIMEOUT_MARGIN) / self.speedup + TIMEOUT_WALL

    async def sleep_mission(self, seconds: float) -> None:
        """Sleep ``seconds`` of mission time (checked against the mission clock)."""
        end = self.clock() + seconds
        deadline = time.monotonic() + self.wall(seconds)
        while (left := end - self.clock()) > 0 and time.monotonic() < deadline:
            await asyncio.sleep(min(max(left / self.speedup, 0.005), 0.1))

    async def _do(self, v: Vehicle, what: str, aw: Awaitable[T], **data: Any) -> T:
        """Run one command, journaling it and its ack (and a pending replan's latency)."""
        if self._replan is not None and self._replan["ready"]:
            self._finish_replan((time.monotonic() - self._replan["t"]) * 1000.0)
        self.record("command", vehicle=v.name, command=what, **data)
        try:
            result = await aw
        except CommandRejected as exc:
            self.record("ack", vehicle=v.name, command=what, result=exc.ack.result_name, reason=exc.reason)
            raise
        except MissionRejected as exc:
            self.record("ack", vehicle=v.name, command=what, result=exc.result_name, reason=exc.reason)
            raise
        except (LinkError, TimeoutError) as exc:
            self.record("ack", vehicle=v.name, command=what, result="timeout", error=str(exc))
            raise
        self.record("ack", vehicle=v.name, command=what, result="MAV_RESULT_ACCEPTED")
        return result

    def rovers(self) -> dict[str, Vehicle]:
        return self.fleet.rovers

    def rover_on_deck(self, v: Vehicle) -> bool:
        c = self.fleet.carrier
        return v.connected and not v.lost and on_deck(v.enu, c.enu, v.on_ground, v.ground_speed)

    async def _wait_telemetry(self) -> None:
        """Wait for positions (and landed states of rovers) of every connected vehicle."""
        async def one(v: Vehicle) -> None:
            with contextlib.suppress(TimeoutError):
                await v.wait_until(lambda v: v.enu is not None and (v is self.fleet.carrier
                                                                    or v.landed_state is not None),
                                   TELEMETRY_TIMEOUT, "first position")

        await asyncio.gather(*(one(v) for v in self.fleet.vehicles.values() if v.connected and not v.lost))
        if self.fleet.carrier.enu is None:
            raise ExecutionError(f"{self.fleet.carrier.name}: no position from the carrier within "
                                 f"{TELEMETRY_TIMEOUT:g} s (is GPS available?)")

    def carrier_pose(self) -> tuple[tuple[float, float, float], float]:
        """The carrier's live ENU position (on the ground) and math heading; the mission's when
        telemetry lacks them."""
        c = self.fleet.carrier
        m = self.mission.deploy_problem() if self.mission.tasks else None
        pos = c.enu
        start = (pos[0], pos[1], 0.0) if pos is not None else (self.mission.carrier.position[0],
                                                               self.mission.carrier.position[1], 0.0)
        if c.heading_deg is not None:
            heading = math.radians(90.0 - c.heading_deg)
            heading = math.atan2(math.sin(heading), math.cos(heading))
        elif m is not None:
            heading = m.heading
        else:
            heading = math.radians(90.0 - self.mission.carrier.heading_deg)
        return start, heading

    async def _plan(self, kind: str, problem: Any) -> Plan:
        import planners

        registry = planners.DEPLOY_PLANNERS if kind == "deploy" else planners.COLLECT_PLANNERS
        given = None
        if self.planner:  # "NAME" for both phases, or "DEPLOY,COLLECT" (fleetctl run)
            parts = [p.strip() for p in self.planner.split(",")]
            given = parts[0] if kind == "deploy" else parts[-1]
        name = given or self.mission.planner_for(kind)
        if name not in registry:
            raise ExecutionError(f"unknown {kind} planner {name!r}; "
                                 f"choose one of {', '.join(sorted(registry))}")
        try:
            plan = await asyncio.to_thread(registry[name], problem)
        except PlanningError as exc:
            raise ExecutionError(f"cannot plan the {'deployment' if kind == 'deploy' else 'collection'} "
                                 f"with {name!r}: {exc}") from None
        self.record("plan", plan=plan.to_json())
        if self.write_plan is not None:
            self.write_plan(kind, plan)
        self.state.event("plan", f"{kind} plan ({name}): {len(plan.stops)} stops, makespan "
                         f"{plan.makespan:.1f} s, computed in {plan.compute_ms:.0f} ms",
                         stops=len(plan.stops), makespan=plan.makespan)
        return plan

    def _compile(self, plan: Plan) -> CompiledPlan:
        try:
            return compile_for_fleet(plan, self.fleet, meet_height=COLLECT_MEET_HEIGHT)
        except CompileError as exc:
            raise ExecutionError(str(exc)) from None

    async def _upload(self, v: Vehicle, items: list[MissionItem]) -> None:
        try:
            await self._do(v, "upload_mission", v.upload_mission(items), items=len(items))
        except MissionRejected as exc:
            why = f" ({exc.reason})" if exc.reason else ""
            raise ExecutionError(f"{v.name} ({self.fleet.urls.get(v.name, '')}) rejected its mission: "
                                 f"{exc.result_name}{why}") from None

    async def _start_carrier(self, compiled: CompiledPlan) -> None:
        c = self.fleet.carrier
        await self._upload(c, list(compiled.carrier))
        try:
            if not c.armed:
                await self._do(c, "arm", c.arm())
            await self._do(c, "start_mission", c.start_mission())
        except CommandRejected as exc:
            raise ExecutionError(f"the carrier {c.name} refused to start its route: {exc}") from None
        except (LinkError, TimeoutError) as exc:
            raise ExecutionError(f"the carrier {c.name} did not answer: {exc}") from None

    async def _release_carrier(self, seq: int | None) -> None:
        if seq is None:
            return
        c = self.fleet.carrier
        try:
            await self._do(c, "set_current", c.set_current(seq), seq=seq)
        except (CommandRejected, LinkError, TimeoutError) as exc:
            raise ExecutionError(f"the carrier {c.name} could not be released from its stop: {exc}") from None

    async def _wait_stop(self, k: int, arrive_seq: int, planned_leg: float) -> float:
        c = self.fleet.carrier
        self.state.stop_index = k + 1
        self.state.set_state(c.name, fs.DRIVING)
        try:
            await c.wait_item_reached(arrive_seq, self.wall(planned_leg))
        except TimeoutError as exc:
            raise ExecutionError(f"the carrier did not reach stop {k + 1}: {exc}") from None
        t = self.clock()
        self.state.set_state(c.name, fs.HOLDING)
        pos = c.enu
        self.state.event("stop_reached", f"{c.name}: stop {k + 1}/{self.state.stop_count} reached",
                         c.name, stop=k + 1, position=pos)
        return t

    # ============================================================================== supervision
    def submit_task_change(self, add: list[Task], remove: list[str], source: str) -> None:
        """Add and/or remove tasks of the running mission (see the module docstring). Safe to
        call from the event loop or from another thread; applied by the supervisor loop."""
        ev = SupervisorEvent("tasks", None, add=tuple(add), remove=tuple(remove), source=source)
        try:
            running: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if self._loop is None or running is self._loop:
            self.supervisor.put(ev)
        else:
            self._loop.call_soon_threadsafe(self.supervisor.put, ev)

    def _begin_replan(self, cause: str, ev: SupervisorEvent, old: Plan | None, **data: Any) -> None:
        if self._replan is not None:  # a second cause before the first plan went out: one replan
            self._replan["cause"] += f"; {cause}"
            return
        self._replan = {"cause": cause, "t": ev.t, "vehicle": ev.vehicle, "old": old, "new": None,
                        "ready": False, **data}

    def _replan_ready(self, new: Plan | None) -> None:
        r = self._replan
        if r is None:
            return
        r["new"], r["ready"] = new, True
        if new is None:
            self._finish_replan(None)

    def _finish_replan(self, latency_ms: float | None) -> None:
        r, self._replan = self._replan, None
        if r is None:
            return
        st = self.state
        st.replans += 1
        old, new = r["old"], r["new"]
        lat = "" if latency_ms is None else f", first new command {latency_ms:.0f} ms after the event"
        what = (f"{len(new.stops)} stops, makespan {new.makespan:.1f} s" if new is not None
                else "nothing left to plan")
        text = f"replan #{st.replans}: {r['cause']} -> {what}{lat}"
        st.last_replan = text
        self.record("replan", n=st.replans, cause=r["cause"], latency_ms=latency_ms,
                    old_plan=old.to_json() if old is not None else None,
                    new_plan=new.to_json() if new is not None else None)
        st.event("replan", text, r.get("vehicle"), n=st.replans, cause=r["cause"], latency_ms=latency_ms)

    async def _race(self, aw: Awaitable[T], handle: Callable[[SupervisorEvent], bool]
                    ) -> tuple[bool, T | None]:
        """Await ``aw`` while handing supervisor events to ``handle``; when ``handle`` returns True
        (replan), ``aw`` is cancelled and ``(False, None)`` returned, else ``(True, result)``."""
        task = asyncio.ensure_future(aw)
        q = self.supervisor.queue
        getter: asyncio.Future[SupervisorEvent] | None = None
        try:
            while True:
                getter = asyncio.ensure_future(q.get())
                done, _ = await asyncio.wait({task, getter}, return_when=asyncio.FIRST_COMPLETED)
                if getter in done:
                    ev, getter = getter.result(), None
                    if handle(ev):
                        return False, None
                    continue
                return True, task.result()
        finally:
            for f in (task, getter):
                if f is not None and not f.done():
                    f.cancel()
                    with contextlib.suppress(asyncio.CancelledError, Exception):
                        await f

    def _drain(self, handle: Callable[[SupervisorEvent], bool]) -> bool:
        """Hand every queued event to ``handle``; True if one asks for a replan."""
        again = False
        q = self.supervisor.queue
        while not q.empty():
            again = handle(q.get_nowait()) or again
        return again

    def _carrier_event(self, ev: SupervisorEvent, airborne: Callable[[], list[str]]) -> list[str]:
        """Carrier lost: no more launches (see :meth:`_carrier_ready`), airborne rovers hold (or land
        when their battery is at the reserve); back: they resume. Returns the rovers sent to land."""
        st = self.state
        rovers = self.rovers()
        landing: list[str] = []
        if ev.kind == "lost":
            self._carrier_ok.clear()
            self._carrier_losses += 1
            reserve = self.mission.rovers.reserve * 100.0
            for rid in airborne():
                v = rovers[rid]
                if v.lost:
                    continue
                low = v.battery_pct is not None and v.battery_pct <= reserve
                if low:
                    landing.append(rid)
                else:
                    self._held.add(rid)
                self._spawn(self._hold_or_land(v, low), f"hold {rid}")
            st.event("carrier_lost", f"{self.fleet.carrier_id}: carrier lost: no launches; airborne rovers "
                     f"hold ({', '.join(sorted(self._held)) or 'none'})", self.fleet.carrier_id)
        else:
            self._carrier_ok.set()
            held, self._held = sorted(self._held), set()
            for rid in held:
                self._spawn(self._resume(rovers[rid]), f"resume {rid}")
            st.event("carrier_back", f"{self.fleet.carrier_id}: carrier back; resuming "
                     f"{', '.join(held) or 'nothing'}", self.fleet.carrier_id)
        return landing

    async def _hold_or_land(self, v: Vehicle, low: bool) -> None:
        try:
            if low:
                await self._do(v, "land", v.land())
                self.state.event("rover_landing", f"{v.name}: battery at the reserve, landing where it is",
                                 v.name)
            else:
                await self._do(v, "pause", v.pause())
        except (CommandRejected, LinkError, TimeoutError) as exc:
            log.warning("%s: could not hold/land: %s", v.name, exc)

    async def _resume(self, v: Vehicle) -> None:
        with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
            await self._do(v, "resume", v.resume())

    async def _carrier_ready(self) -> None:
        """Wait (bounded) until the carrier's link is up."""
        if self._carrier_ok.is_set() and not self.fleet.carrier.lost:
            return
        try:
            await self.fleet.carrier.wait_until(lambda v: not v.lost, self.wall(CARRIER_OUTAGE_MAX),
                                                "carrier back")
        except TimeoutError:
            raise ExecutionError(f"the carrier {self.fleet.carrier_id} stayed lost for more than "
                                 f"{CARRIER_OUTAGE_MAX:g} s; rovers in the field hold where they are"
                                 ) from None

    async def _reach_stop(self, k: int, arrive_seq: int, planned_leg: float) -> float:
        """:meth:`_wait_stop`, waiting out carrier link outages on the way."""
        while True:
            losses = self._carrier_losses
            try:
                return await self._wait_stop(k, arrive_seq, planned_leg)
            except ExecutionError:
                if losses == self._carrier_losses and not self.fleet.carrier.lost:
                    raise
                await self._carrier_ready()

    def _flight_path(self, rm: RoverMission, start: Vec3) -> list[Vec3]:
        """Where a rover flying ``rm`` from ``start`` should be (its items' positions)."""
        origin = self.fleet.carrier.origin
        pts: list[Vec3] = [start]
        if origin is None:
            return pts
        for it in rm.items:
            if it.frame == M.MAV_FRAME_GLOBAL:  # ArduPilot home placeholder
                continue
            pts.append(item_position(it, origin))
        return pts

    # ============================================================================== deployment
    async def deploy(self) -> PhaseResult:
        """Plan from the live state and fly the deployment, replanning on supervisor events;
        returns what was reached (and why anything was not)."""
        res = PhaseResult("deploy")
        st = self.state
        st.set_phase("plan")
        await self._wait_telemetry()
        self.supervisor.start()
        rovers = self.rovers()
        carrier_id = self.fleet.carrier_id
        deck = [rid for rid, v in rovers.items() if self.rover_on_deck(v)]
        if len(deck) < len(self.tasks):  # a landed state may still be on its way (packet loss)
            async def settle(v: Vehicle) -> None:
                with contextlib.suppress(TimeoutError):
                    await v.wait_until(self.rover_on_deck, DECK_CHECK_TIMEOUT, "on the deck")

            await asyncio.gather(*(settle(v) for rid, v in rovers.items()
                                   if rid not in deck and v.connected and not v.lost))
            deck = [rid for rid, v in rovers.items() if self.rover_on_deck(v)]
        for rid, v in rovers.items():
            away = fs.LOST if not v.connected or v.lost else fs.LANDED
            st.set_state(rid, fs.ON_DECK if rid in deck else away)
        if len(deck) < len(self.tasks):
            raise ExecutionError(f"{len(deck)} rover(s) on the carrier's deck ({', '.join(deck) or 'none'}) "
                                 f"for {len(self.tasks)} tasks: every task needs a rover on the deck")
        pool: dict[str, Task] = dict(self.tasks)  # tasks no rover has been launched for (yet / again)
        flying: dict[str, str] = {}  # task -> rover flying to it
        watchers: dict[str, asyncio.Task[None]] = {}  # task -> its watcher
        reached: dict[str, float] = {}
        launched: list[str] = []  # rovers that left the deck
        unusable: set[str] = set()  # lost while on the deck
        reasons: dict[str, str] = {}  # task -> why it is not (yet) reached
        plan: Plan | None = None
        t0: float | None = None
        deploy_range = self.mission.rovers.deploy_range

        def airborne() -> list[str]:
            return list(flying.values())

        def drop_flying(task: str) -> str:
            rid = flying.pop(task)
            w = watchers.pop(task, None)
            if w is not None:
                w.cancel()
            self.supervisor.expect(rid, None)
            return rid

        def handle(ev: SupervisorEvent) -> bool:
            rid = ev.vehicle
            if ev.kind in ("lost", "back") and rid == carrier_id:
                landing = self._carrier_event(ev, airborne)
                landed = [(t, r) for t, r in flying.items() if r in landing]
                for task, r in landed:  # it will not reach its task: the task goes back to the pool
                    drop_flying(task)
                    pool[task] = self.tasks[task]
                    reasons[task] = f"its rover {r} landed at the battery reserve while the carrier was lost"
                    res.rejoined.append(r)  # a rover to collect where it landed
                    st.event("task_returned", f"{task}: {r} landed at the battery reserve; the task goes "
                             "back to the pool", r, task=task)
                if landed:
                    self._begin_replan(f"{', '.join(r for _, r in landed)} landed at the battery reserve "
                                       "(carrier lost)", ev, plan)
                return bool(landed)
            if ev.kind == "lost" and rid is not None:
                st.set_state(rid, fs.LOST)
                task = next((t for t, r in flying.items() if r == rid), None)
                if task is not None:
                    drop_flying(task)
                    pool[task] = self.tasks[task]
                    reasons[task] = f"its rover {rid} was lost in flight"
                    st.event("task_returned", f"{task}: {rid} lost in flight; the task goes back to the pool",
                             rid, task=task)
                    self._begin_replan(f"{rid} lost in flight (task {task})", ev, plan)
                    return True
                if rid not in launched:
                    unusable.add(rid)
                    st.event("rover_unusable", f"{rid}: lost on the deck: unusable, a spare takes its place",
                             rid)
                return False
            if ev.kind == "back" and rid is not None:
                if rid in unusable:
                    unusable.discard(rid)
                    st.set_state(rid, fs.ON_DECK)
                    st.event("rover_rejoined", f"{rid}: back on the deck: a spare again", rid)
                    starved = [t for t in self.tasks
                               if t not in pool and t not in flying and t not in reached]
                    if starved:
                        for t in starved:
                            pool[t] = self.tasks[t]
                        self._begin_replan(f"{rid} back on the deck (for {', '.join(starved)})", ev, plan)
                        return True
                elif rid in launched:
                    task = next((t for t, r in res.assignment.items() if r == rid), None)
                    on = task is not None and flying.get(task) == rid
                    st.set_state(rid, st.vehicles[rid].state if on else fs.ON_TASK)
                    if not on:
                        res.rejoined.append(rid)
                    st.event("rover_rejoined", f"{rid}: link back" + ("" if on else
                             ": rejoins as a rover to collect"), rid)
                return False
            if ev.kind == "tasks":
                why = validate_task_change(self.tasks, ev.add, ev.remove, deploy_range)
                free = sum(1 for r in deck if r not in launched and r not in unusable
                           and r not in self.refused and not rovers[r].lost)
                need = len(pool) + len(ev.add) - sum(1 for r in ev.remove if r in pool)
                if why is None and need > free:
                    why = f"{need} tasks to fly but only {free} rover(s) left on the deck"
                if why is not None:
                    self.supervisor.reject(why, ev.source)
                    return False
                again = bool(ev.add)
                for tid in ev.remove:
                    self.tasks.pop(tid, None)
                    res.tasks_removed.append(tid)
                    reasons.pop(tid, None)
                    reached.pop(tid, None)
                    if tid in pool:
                        del pool[tid]
                        again = True
                    if tid in flying:
                        r = drop_flying(tid)
                        res.rejoined.append(r)
                        st.event("rover_released", f"{r}: its task {tid} was removed; it holds there to be "
                                 "collected", r, task=tid)
                    res.assignment.pop(tid, None)
                for t in ev.add:
                    self.tasks[t.id] = t
                    pool[t.id] = t
                    res.tasks_added.append(t.id)
                st.event("tasks_changed", f"tasks changed ({ev.source}): added "
                         f"{', '.join(t.id for t in ev.add) or 'none'}, "
                         f"removed {', '.join(ev.remove) or 'none'}",
                         None, add=[t.id for t in ev.add], remove=list(ev.remove), source=ev.source)
                if again:
                    self._begin_replan(f"tasks changed ({ev.source}): +{len(ev.add)} -{len(ev.remove)}",
                                       ev, plan)
                return again
            if ev.kind == "battery_low" and rid is not None:
                st.event("battery_low", f"{rid}: battery {ev.data.get('battery_pct')}% at or below the "
                         f"reserve the plan assumed", rid, **ev.data)
            elif ev.kind == "off_course" and rid is not None:
                st.event("off_course", f"{rid}: off course ({ev.data.get('distance')} m from its path)",
                         rid, **ev.data)
            return False

        async def watch(rid: str, task: str, leg: RoverLeg, takeoff_seq: int, assert_t0: float) -> None:
            v = rovers[rid]
            target = leg.end

            def check(v: Vehicle) -> bool:
                if st.vehicles[rid].state == fs.CLIMBING and (v.mission_current or 0) > takeoff_seq:
                    st.set_state(rid, fs.EN_ROUTE)
                p = v.enu
                return (p is not None and math.dist(p, target) <= REACH_RADIUS
                        and (v.ground_speed or 0.0) < HOLD_SPEED)

            tries = 0
            while True:
                losses = self._carrier_losses
                remaining = max(leg.arrive - (self.clock() - assert_t0), 0.0)
                try:
                    await v.wait_until(check, self.wall(remaining), f"task {task}")
                    break
                except TimeoutError:
                    tries += 1
                    if (losses == self._carrier_losses and not self.fleet.carrier.lost) or tries > 3:
                        reasons[task] = f"{rid} did not reach it in time"
                        st.event("task_timeout", f"{rid}: did not reach {task} in time", rid, task=task)
                        flying.pop(task, None)
                        return
            flying.pop(task, None)
            watchers.pop(task, None)
            self.supervisor.expect(rid, None)
            reached[task] = self.clock() - (t0 if t0 is not None else assert_t0)
            reasons.pop(task, None)
            st.set_state(rid, fs.ON_TASK)
            st.event("task_reached", f"{rid}: reached {task} (at {reached[task]:.1f} s, planned "
                     f"{leg.arrive:.1f} s of its plan)", rid, task=task, flown=reached[task],
                     planned=leg.arrive)

        async def fly(plan: Plan, compiled: CompiledPlan, deck_now: list[str], plan_t0: float) -> None:
            slots = compiled.rovers  # planned rover id -> its mission (the rover flying it may differ)
            spares = [rid for rid in deck_now if rid not in slots]
            self.record("spares", rovers=spares)
            used: set[str] = set(slots)

            def take_spare() -> str | None:
                for rid in spares:
                    r = rovers[rid]
                    if (rid not in used and rid not in self.refused and rid not in unusable
                            and rid not in launched and r.connected and not r.lost):
                        used.add(rid)
                        return rid
                return None

            async def launch(slot: RoverMission, leg: RoverLeg, at: Vec3) -> None:
                task = slot.task or ""
                rid: str | None = slot.rover
                while rid is not None:
                    v = rovers[rid]
                    await self._carrier_ready()  # no launches while the carrier is lost
                    if rid in unusable or rid in launched:
                        rid = take_spare()
                        continue
                    # telemetry of rover and carrier may be of different moments
                    if not self.rover_on_deck(v):
                        with contextlib.suppress(TimeoutError):
                            await v.wait_until(self.rover_on_deck, DECK_CHECK_TIMEOUT, "on the deck")
                    if not self.rover_on_deck(v):
                        st.event("rover_skipped", f"{rid}: not on the deck, a spare takes {task}", rid)
                        rid = take_spare()
                        continue
                    try:
                        if uploaded.get(rid) != (id(compiled), slot.rover):
                            await self._upload(v, list(slot.items))
                            uploaded[rid] = (id(compiled), slot.rover)
                        await self._do(v, "arm", v.arm())
                    except CommandRejected as exc:
                        self.refused.add(rid)
                        st.set_state(rid, fs.REFUSED)
                        spare = take_spare()
                        reason = exc.reason or exc.ack.result_name
                        then = f"spare {spare} takes {task}" if spare else f"no spare left for {task}"
                        st.event("rover_refused", f"{rid}: refused to arm ({reason}); {then}",
                                 rid, reason=reason, spare=spare, task=task)
                        if spare is not None:
                            res.substitutions.append({"refused": rid, "spare": spare, "task": task})
                        rid = spare
                        continue
                    except (ExecutionError, LinkError, TimeoutError) as exc:
                        spare = take_spare()
                        st.event("rover_failed", f"{rid}: {exc}; " + (f"spare {spare} takes {task}" if spare
                                                                      else f"no spare left for {task}"),
                                 rid, spare=spare, task=task)
                        rid = spare
                        continue
                    try:
                        await self._do(v, "start_mission", v.start_mission())
                        tk = _takeoff_seq(slot)
                        # a task on the ground may be left again before a position shows it
                        await v.wait_until(
                            lambda v, tk=tk: ((v.relative_alt or 0.0) > AIRBORNE_HEIGHT
                                              or tk in v.items_reached
                                              or (v.mission_current or -1) > tk),
                            self.wall(5.0), "lift-off")
                    except (CommandRejected, LinkError, TimeoutError) as exc:
                        st.event("rover_failed", f"{rid}: did not take off ({exc})", rid, task=task)
                        with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
                            await v.disarm()
                        rid = take_spare()
                        continue
                    launched.append(rid)
                    pool.pop(task, None)
                    if task not in self.tasks:  # removed while it was being launched
                        res.rejoined.append(rid)
                        st.set_state(rid, fs.ON_TASK)
                        return
                    res.assignment[task] = rid
                    flying[task] = rid
                    st.set_state(rid, fs.CLIMBING, task=task)
                    st.event("rover_launched", f"{rid}: launched for {task} at stop {slot.stop + 1}", rid,
                             task=task, stop=slot.stop + 1)
                    self.supervisor.expect(rid, self._flight_path(slot, at))
                    watchers[task] = self._spawn(watch(rid, task, leg, _takeoff_seq(slot), plan_t0),
                                                 f"watch {rid}")
                    return
                pool.pop(task, None)
                reasons[task] = "no rover left on the deck to fly it (every spare used, lost or refused)"
                st.event("task_unserved", f"{task}: no rover left to fly it", None, task=task)

            prev = 0.0
            for k, (stop, items) in enumerate(zip(plan.stops, compiled.stops, strict=True)):
                ok, arrived = await self._race(self._reach_stop(k, items.arrive_seq, stop.arrive - prev),
                                               handle)
                if not ok or arrived is None:
                    return  # the rest of the route is thrown away
                prev = stop.depart
                at = (stop.position[0], stop.position[1], 0.0)
                launches = [launch(slots[leg.rover], leg, at) for leg in stop.rovers if leg.task in pool]
                unload = self.sleep_mission(
                    max(arrived + self.mission.carrier.unload_time - self.clock(), 0.0))
                await asyncio.gather(unload, *launches)
                if self._drain(handle) and k + 1 < len(plan.stops) or pool and k + 1 == len(plan.stops):
                    return  # replan from this stop (the carrier holds here)
                await self._release_carrier(items.release_seq)
                if items.release_seq is not None:
                    self.record("carrier_released", stop=k + 1)

        uploaded: dict[str, tuple[int, str]] = {}  # rover -> (compiled plan, slot) whose mission it holds
        while True:
            self._drain(handle)
            if pool:
                usable = [rid for rid in deck if rid not in launched and rid not in unusable
                          and rid not in self.refused and not rovers[rid].lost]
                tasks = list(pool.values())
                for t in tasks[len(usable):]:
                    del pool[t.id]
                    reasons[t.id] = "no spare rover left on the deck"
                    st.event("task_unserved", f"{t.id}: no spare rover left on the deck", None, task=t.id)
                tasks = tasks[:len(usable)]
            if not pool:
                self._replan_ready(None)
            else:
                await self._carrier_ready()
                start, heading = self.carrier_pose()
                problem = dataclasses.replace(self.mission.deploy_problem(), start=start, heading=heading,
                                              tasks=tuple(tasks), rovers=tuple(usable))
                plan = await self._plan("deploy", problem)
                compiled = self._compile(plan)
                self._replan_ready(plan)
                if t0 is None:
                    res.plan, res.planned = plan, plan.makespan
                    st.set_phase("deploy", plan.makespan, len(plan.stops))

                    async def pre_upload(slot: RoverMission, compiled: CompiledPlan = compiled) -> None:
                        try:
                            await self._upload(rovers[slot.rover], list(slot.items))
                            uploaded[slot.rover] = (id(compiled), slot.rover)
                        except (ExecutionError, LinkError, TimeoutError) as exc:
                            log.warning("%s: upload failed (%s); a spare will fly %s", slot.rover, exc,
                                        slot.task)

                    await asyncio.gather(*(pre_upload(s) for s in compiled.rovers.values()))
                else:
                    st.planned = (self.clock() - t0) + plan.makespan
                    st.stop_count, st.stop_index = len(plan.stops), 0
                await self._start_carrier(compiled)
                plan_t0 = self.clock()
                if t0 is None:
                    t0 = res.started = st.phase_started = plan_t0
                    st.event("carrier_started", f"{carrier_id}: route started ({len(plan.stops)} stops)",
                             carrier_id)
                await fly(plan, compiled, usable, plan_t0)
                continue
            pending = [w for w in watchers.values() if not w.done()]
            if not pending:
                break
            getter = asyncio.ensure_future(self.supervisor.queue.get())
            try:
                done, _ = await asyncio.wait({getter, *pending}, timeout=self.wall(60.0),
                                             return_when=asyncio.FIRST_COMPLETED)
            finally:
                if not getter.done():
                    getter.cancel()
                    with contextlib.suppress(asyncio.CancelledError):
                        await getter
            if getter.done() and not getter.cancelled():
                handle(getter.result())
        self.state.set_state(carrier_id, fs.IDLE)
        order = list(self.tasks)
        res.tasks_reached = [t for t in order if t in reached]
        res.tasks_unserved = [t for t in order if t not in reached]
        res.unserved_reasons = {t: reasons.get(t, "not reached") for t in res.tasks_unserved}
        res.tasks_all = order
        res.launched = launched
        res.rovers_lost = [rid for rid, v in rovers.items() if v.lost]
        res.complete = not res.tasks_unserved
        if res.complete and reached:
            res.flown = max(reached.values())
        elif res.complete:
            res.flown = 0.0
        return res

    # ============================================================================== collection
    async def collect(self, rover_ids: Iterable[str] | None = None) -> PhaseResult:
        """Plan the collection from live positions and batteries and fly it.

        ``rover_ids``: the rovers to collect (default: every connected rover not on the deck).
        A rover lost on the way is removed: the carrier keeps the others' meeting points (they are
        flying there on the energy they have left, ch. 5.5.3) and drops stops left empty; a lost
        rover that comes back is collected in a further round planned from the live state."""
        res = PhaseResult("collect")
        st = self.state
        st.set_phase("plan")
        await self._wait_telemetry()
        self.supervisor.start()
        rovers = self.rovers()
        carrier_id = self.fleet.carrier_id
        ids = list(rover_ids) if rover_ids is not None else [
            rid for rid, v in rovers.items() if v.connected and not self.rover_on_deck(v)]
        lost = [rid for rid in ids
                if not rovers[rid].connected or rovers[rid].lost or rovers[rid].enu is None]
        res.rovers_lost = list(lost)
        for rid in lost:
            st.set_state(rid, fs.LOST)
        todo = [rid for rid in ids if rid not in lost]
        loaded: dict[str, float] = {}
        t0: float | None = None
        last_load: float | None = None
        plan: Plan | None = None
        in_round: set[str] = set()  # rovers the current round's carrier route still serves
        rp = self.mission.rovers

        def airborne() -> list[str]:
            return [rid for rid in in_round if rid not in loaded]

        def handle(ev: SupervisorEvent) -> bool:
            rid = ev.vehicle
            if ev.kind in ("lost", "back") and rid == carrier_id:
                self._carrier_event(ev, airborne)
                return False
            if ev.kind == "lost" and rid is not None and rid in ids and rid not in loaded:
                st.set_state(rid, fs.LOST)
                if rid not in res.rovers_lost:
                    res.rovers_lost.append(rid)
                self.supervisor.expect(rid, None)
                if rid in in_round:
                    in_round.discard(rid)
                    self._begin_replan(f"{rid} lost during the collection", ev, plan)
                    return True
                return False
            if ev.kind == "back" and rid is not None and rid in res.rovers_lost and rid not in loaded:
                res.rovers_lost.remove(rid)
                if rid not in todo:
                    todo.append(rid)
                st.set_state(rid, fs.RETURNING if rid in in_round else fs.ON_TASK)
                st.event("rover_rejoined", f"{rid}: link back: rejoins the rovers to collect", rid)
                return False
            if ev.kind == "tasks":
                self.supervisor.reject("the deployment is over; tasks can change only while deploying",
                                       ev.source)
            elif ev.kind == "battery_low" and rid is not None:
                st.event("battery_low", f"{rid}: battery {ev.data.get('battery_pct')}% at or below the "
                         f"reserve the plan assumed", rid, **ev.data)
                if self.fleet.carrier.lost and rid in airborne():
                    self._held.discard(rid)
                    self._spawn(self._hold_or_land(rovers[rid], True), f"land {rid}")
            elif ev.kind == "off_course" and rid is not None:
                st.event("off_course", f"{rid}: off course ({ev.data.get('distance')} m from its path)",
                         rid, **ev.data)
            return False

        while True:
            self._drain(handle)
            batch = [rid for rid in todo if rid not in loaded and rid not in res.rovers_lost
                     and rid not in res.rovers_unreachable]
            if not batch:
                self._replan_ready(None)
                break
            await self._carrier_ready()
            todo[:] = [rid for rid in todo if rid not in batch]  # a rover back later joins again
            # plan from fresh batteries, not the last ~1 Hz stream sample
            await asyncio.gather(*(rovers[rid].refresh_battery() for rid in batch))
            crs = []
            for rid in batch:
                v = rovers[rid]
                p = v.enu
                if p is None:
                    res.rovers_lost.append(rid)
                    continue
                rng = range_from_percent(v.battery_pct, rp.reserve, rp.endurance_range)
                if rng is None:
                    rng = (1.0 - rp.reserve) * rp.endurance_range
                    log.warning("%s reports no battery; assuming a full one", rid)
                self.record("rover_state", vehicle=rid, position=p, battery_pct=v.battery_pct, range=rng)
                if rng < max(p[2], 0.0):  # cannot even land below itself: out of the carrier's reach
                    res.rovers_unreachable.append(rid)
                    st.event("rover_unreachable", f"{rid}: {rng:.1f} m of range left at {p[2]:.1f} m up: "
                             "cannot reach the ground, not collected", rid, range=rng, height=p[2])
                    continue
                crs.append(CollectRover(rid, (p[0], p[1], max(p[2], 0.0)), rng))
            if not crs:
                continue
            start, heading = self.carrier_pose()
            problem = CollectProblem(self.mission.carrier.spec(), rp.motion(), start, heading, tuple(crs),
                                     **self.mission.environment())
            plan = await self._plan("collect", problem)
            compiled = self._compile(plan)
            self._replan_ready(plan)
            if t0 is None:
                res.plan, res.planned = plan, plan.makespan
                st.set_phase("collect", plan.makespan, len(plan.stops))
            else:
                st.planned = (self.clock() - t0) + plan.makespan
                st.stop_count, st.stop_index = len(plan.stops), 0
            in_round.update(leg.rover for leg in plan.legs())
            await self._collect_round(plan, compiled, res, loaded, in_round, handle, t0)
            if t0 is None:
                t0 = res.started
            last_load = res.flown if res.flown is not None else last_load
            res.flown = None
        self.state.set_state(carrier_id, fs.IDLE)
        res.rovers_loaded = [rid for rid in ids if rid in loaded]
        res.rovers_lost = [rid for rid in res.rovers_lost if rid not in loaded]
        # complete: every rover loaded, except those out of reach and those lost before it began
        res.complete = all(rid in loaded or rid in res.rovers_unreachable or rid in lost for rid in ids)
        if t0 is None:  # nothing flown
            res.planned = 0.0
            res.complete = res.complete and not lost
            st.event("nothing_to_collect", "no rover to collect" + (f" ({len(lost)} lost)" if lost else ""))
        res.flown = (last_load if last_load is not None else 0.0) if res.complete else None
        return res

    async def _collect_round(self, plan: Plan, compiled: CompiledPlan, res: PhaseResult,
                             loaded: dict[str, float],
                             in_round: set[str], handle: Callable[[SupervisorEvent], bool],
                             t0: float | None) -> None:
        """Fly one collection plan; rovers lost on the way are dropped from it (see :meth:`collect`)."""
        st = self.state
        rovers = self.rovers()
        land_seq: dict[str, int] = {}
        hold_seq: dict[str, int] = {}
        items_of: dict[str, list[MissionItem]] = {}
        for rid, rm in compiled.rovers.items():
            items = list(rm.items)
            hold = dataclasses.replace(items[rm.target_seq], command=M.MAV_CMD_NAV_LOITER_UNLIM)
            items.insert(rm.target_seq + 1, hold)
            hold_seq[rid], land_seq[rid] = rm.target_seq + 1, rm.final_seq + 1
            items_of[rid] = items
        results = await asyncio.gather(*(self._upload(rovers[rid], items) for rid, items in items_of.items()),
                                       return_exceptions=True)
        failed = {rid: r for rid, r in zip(items_of, results, strict=True) if isinstance(r, BaseException)}
        for rid, exc in failed.items():
            st.event("rover_failed", f"{rid}: mission upload failed ({exc})", rid)
        await self._start_carrier(compiled)
        if t0 is None:
            t0 = res.started = st.phase_started = self.clock()

        async def go(rid: str) -> None:
            v = rovers[rid]
            try:
                if not v.armed:
                    await self._do(v, "arm", v.arm())
                await self._do(v, "start_mission", v.start_mission())
                st.set_state(rid, fs.RETURNING)
                self.supervisor.expect(rid, self._flight_path(compiled.rovers[rid], v.enu or (0.0, 0.0, 0.0)))
            except (CommandRejected, LinkError, TimeoutError) as exc:
                st.event("rover_failed", f"{rid}: cannot start its way back ({exc})", rid)
                failed[rid] = exc

        await asyncio.gather(*(go(rid) for rid in items_of if rid not in failed))
        for rid in failed:
            in_round.discard(rid)
        st.event("collection_started", f"collecting {len(items_of) - len(failed)} rovers", None)

        async def bring_in(rid: str, leg_arrive: float, start: float) -> None:
            v = rovers[rid]
            if rid in failed or rid not in in_round:
                return
            try:
                while True:
                    losses = self._carrier_losses
                    try:
                        await v.wait_until(
                            lambda v: ((v.mission_current or 0) >= hold_seq[rid] or self.rover_on_deck(v)
                                       or v.lost),
                            self.wall(max(leg_arrive - (self.clock() - start), 0.0)), "meeting point")
                        break
                    except TimeoutError:
                        if losses == self._carrier_losses and not self.fleet.carrier.lost:
                            raise
                if v.lost:
                    return
                if not self.rover_on_deck(v):
                    await self._do(v, "set_current", v.set_current(land_seq[rid]), seq=land_seq[rid])
                    st.set_state(rid, fs.LANDED)
                await v.wait_until(lambda v: self.rover_on_deck(v) or v.lost, self.wall(10.0),
                                   "landing on the carrier")
                if v.lost:
                    return
            except (CommandRejected, LinkError, TimeoutError) as exc:
                st.event("rover_failed", f"{rid}: not loaded ({exc})", rid)
                return
            assert t0 is not None
            loaded[rid] = self.clock() - t0
            in_round.discard(rid)
            self.supervisor.expect(rid, None)
            st.set_state(rid, fs.LOADED)
            st.event("rover_loaded", f"{rid}: loaded on the carrier at {loaded[rid]:.1f} s", rid,
                     flown=loaded[rid])

        start = self.clock()
        stops = list(plan.stops)
        cstops = list(compiled.stops)
        k, prev = 0, 0.0
        while k < len(stops):
            stop, items = stops[k], cstops[k]
            ok, _ = await self._race(self._reach_stop(k, items.arrive_seq, stop.arrive - prev), handle)
            if not ok:
                stops, cstops, start = await self._trim_collection(plan, stops[k:], cstops[k:], in_round)
                k, prev = 0, 0.0
                continue
            prev = stop.depart
            await asyncio.gather(*(bring_in(leg.rover, leg.arrive, start) for leg in stop.rovers))
            await self.sleep_mission(self.mission.carrier.load_time)
            res.flown = self.clock() - t0
            if self._drain(handle) and k + 1 < len(stops):
                stops, cstops, start = await self._trim_collection(plan, stops[k + 1:], cstops[k + 1:],
                                                                   in_round)
                k, prev = 0, 0.0
                continue
            await self._release_carrier(items.release_seq)
            if items.release_seq is not None:
                self.record("carrier_released", stop=k + 1)
            k += 1
        for rid in list(in_round):  # not loaded in this round: lost, or a later round takes them
            if rid not in loaded:
                in_round.discard(rid)

    async def _trim_collection(self, plan: Plan, rest: list[Stop], rest_items: list[StopItems],
                               in_round: set[str]) -> tuple[list[Stop], list[StopItems], float]:
        """The rest of a collection route without the rovers no longer in it: the others keep their
        meeting points; stops left empty are dropped and the carrier re-routed from where it is."""
        keep: list[Stop] = []
        for s in rest:
            legs = [leg for leg in s.rovers if leg.rover in in_round]
            if legs:
                keep.append(Stop(s.position, [], legs, s.arrive, s.depart))
        start, heading = self.carrier_pose()
        prev = start
        for s in keep:
            s.carrier_path = [prev, s.position]
            prev = s.position
        new = Plan("collect", plan.planner, start, heading, keep,
                   makespan=max((s.depart for s in keep), default=0.0),
                   notes=["trimmed: lost rovers removed"])
        if [s.position for s in keep] == [s.position for s in rest] and keep:
            self._replan_ready(new)  # the route itself is unchanged: no new command
            self._finish_replan(None)
            return keep, rest_items, self.clock()
        if not keep:
            self._replan_ready(None)
            return [], [], self.clock()
        self.record("plan", plan=new.to_json())
        compiled = self._compile(new)
        self._replan_ready(new)
        await self._start_carrier(compiled)
        return keep, list(compiled.stops), self.clock()

    # ============================================================================== abort
    async def hold_airborne(self, timeout: float = 5.0) -> list[str]:
        """Command every airborne rover (and the carrier) to hold where it is; returns who was told."""
        told: list[str] = []

        async def hold(v: Vehicle) -> None:
            try:
                async with asyncio.timeout(timeout):
                    await self._do(v, "hold", v.set_mode("HOLD"))
                told.append(v.name)
            except Exception as exc:  # noqa: BLE001 - best effort on the way out
                log.warning("%s: could not command hold: %s", v.name, exc)

        targets = [v for v in self.rovers().values() if v.connected and not v.lost
                   and (v.on_ground is False or (v.relative_alt or 0.0) > AIRBORNE_HEIGHT)]
        c = self.fleet.carrier
        if c.connected and not c.lost and c.armed:
            targets.append(c)
        await asyncio.gather(*(hold(v) for v in targets))
        if told:
            self.state.event("hold", f"commanded to hold: {', '.join(told)}", None, vehicles=told)
        return told


__all__ = ["COLLECT_MEET_HEIGHT", "REACH_RADIUS", "ExecutionError", "Executor", "PhaseResult"]


def _takeoff_seq(slot: RoverMission) -> int:
    """Index of the NAV_TAKEOFF item of a compiled rover mission (-1 if it has none)."""
    return next((i for i, it in enumerate(slot.items) if it.command == M.MAV_CMD_NAV_TAKEOFF), -1)


# ================================================================================== a whole run


class View:
    """What the runner shows while flying (:mod:`fleetctl.views.dashboard` implements it)."""

    def start(self, state: FleetState, fleet: Fleet | None) -> None:  # pragma: no cover - interface
        pass

    async def stop(self) -> None:  # pragma: no cover - interface
        pass


@dataclass
class RunOutcome:
    exit_code: int  # 0 complete, 1 not complete / failed, 130 interrupted
    summary: dict[str, Any]
    run_dir: Any = None
    error: str | None = None


EXIT_OK = 0
EXIT_FAILED = 1
EXIT_INTERRUPTED = 130


def sim_mission_dict(mission: Mission, command: str = "deploy") -> dict[str, Any]:
    """The mission dict the embedded simulator is started from: the file as written, with the
    rover units spelled out (the file may leave them to defaults). For ``collect`` the rovers
    named in the mission's ``collection`` section start in the field at their positions (the
    others on the deck); without that section a collection on the simulator is refused."""
    import copy

    d = copy.deepcopy(mission.raw)
    if mission.origin is None:
        raise ExecutionError(f"{mission.path or mission.name}: the mission has no origin; flying needs "
                             "WGS84 coordinates: add origin: {lat, lon, alt} to the mission file")
    placed: dict[str, Any] = {}
    if command == "collect":
        if not mission.collection:
            raise ExecutionError(
                f"{mission.path or mission.name}: 'collect' on the simulated fleet needs a 'collection:' "
                "section (where the rovers are); the simulated rovers otherwise start on the carrier's "
                "deck. Add one, or fly 'fleetctl run' (deploy, dwell, collect)")
        placed = {r.id: r.position for r in mission.collection}
    units = []
    for u in mission.rovers.units:
        unit: dict[str, Any] = {"id": u.id, "sysid": u.sysid}
        if u.connection is not None:
            unit["connection"] = u.connection
        if u.id in placed:
            unit["position"] = [float(c) for c in placed[u.id]]
        units.append(unit)
    rovers = dict(d["rovers"])
    rovers.pop("fleet", None)
    rovers["units"] = units
    d["rovers"] = rovers
    c = dict(d["carrier"])
    c.setdefault("id", mission.carrier.id)
    c.setdefault("sysid", mission.carrier.sysid)
    d["carrier"] = c
    return d


async def execute(
    mission: Mission, command: str, *, speedup: float | None = None, planner: str | None = None,
    dwell: float | None = None, summary_path: Any = None, runs_dir: Any = "runs", view: View | None = None,
    connect_timeout: float = 10.0, endpoints: dict[str, str] | None = None,
    on_sim: Callable[[Any], None] | None = None, sim: Any = None, clock_speedup: float | None = None,
    mqtt: Any = None,
) -> RunOutcome:
    """Fly ``command`` (``deploy`` | ``collect`` | ``run``) of ``mission`` end to end: start the
    embedded simulator for ``connection: sim``, connect, fly, and write the records. Cancelling
    the task (Ctrl-C) commands airborne rovers to hold, writes journal and summary and returns
    exit code 130.

    ``sim``: an already running ``sitl.SimFleet`` to fly against (its endpoints, its simulated clock
    and speedup; tests and benchmarks use it to look at the simulated world). ``on_sim`` is called
    with the embedded simulator once it runs. ``clock_speedup``: vehicles that run that much faster
    than the wall clock elsewhere (a simulator in another process): mission time = wall x it.
    ``mqtt``: a :class:`fleetctl.bus.BusConfig` (default: from the mission's ``mqtt:`` section)."""
    from fleetctl.journal import SUMMARY_SCHEMA, Journal, run_dir_for, write_summary
    from fleetctl.mavlink.fleet import FleetConnectError, connect_fleet

    if command not in ("deploy", "collect", "run"):
        raise ValueError(f"unknown command {command!r}")
    if sim is not None:
        endpoints = dict(sim.endpoints)
    uses_sim = sim is None and endpoints is None and (mission.carrier.connection == "sim"
                                      or any(u.connection == "sim" for u in mission.rovers.units))
    sim_cm: Any = None
    clock: Callable[[], float] = time.monotonic
    scale = 1.0
    if clock_speedup is not None and sim is None:
        scale = float(clock_speedup)
        clock = lambda: time.monotonic() * scale  # noqa: E731
    if sim is not None:
        ext = sim
        clock = lambda: ext.sim_time  # noqa: E731
        scale = float(sim.speedup)
    if uses_sim:
        from sitl import FleetConfig, SimFleet

        cfg = FleetConfig.from_mission_dict(sim_mission_dict(mission, command), speedup=speedup)
        scale = cfg.speedup
    journal = Journal(run_dir_for(mission.name, runs_dir))
    state = FleetState(mission)
    state.mission_clock = clock
    state.add_listener(journal.on_event)
    journal.start()
    from fleetctl.bus.client import start_bus

    bus = start_bus(mission, mqtt, journal, state, view)  # None when the mission has no MQTT bus
    journal.write("run", mission=mission.name, command=command, file=str(mission.path or ""),
                  sim=uses_sim, speedup=scale)
    results: dict[str, PhaseResult] = {}
    error: str | None = None
    interrupted = False
    fleet: Fleet | None = None
    executor: Executor | None = None
    refresher: asyncio.Task[None] | None = None
    dwell_flown: float | None = None

    def write_plan(kind: str, plan: Plan) -> None:
        name = "plan.json" if kind == "deploy" or command == "collect" else "plan-collect.json"
        journal.write_json(name, plan.to_json())

    try:
        if uses_sim:
            sim_cm = SimFleet(cfg)
            sim = await sim_cm.__aenter__()
            clock = lambda: sim.sim_time  # noqa: E731
            state.mission_clock = clock
            endpoints = dict(sim.endpoints)
            journal.write("sim_started", endpoints=endpoints, speedup=scale)
            if command == "collect" and mission.collection:
                rp = mission.rovers
                for cr in mission.collection:  # battery: range = (rem - reserve) x endurance
                    sim.rover(cr.id).battery = min(1.0, rp.reserve + cr.range / rp.endurance_range)
            if on_sim is not None:
                on_sim(sim)
        state.phase = "connect"
        if view is not None:
            view.start(state, None)
        try:
            fleet = await connect_fleet(mission, endpoints, timeout=connect_timeout)
        except FleetConnectError as exc:
            raise ExecutionError(str(exc)) from None
        except LinkError as exc:
            raise ExecutionError(f"cannot open the link: {exc}") from None
        fleet.add_tap(journal.tlog)
        for vid, v in fleet.vehicles.items():
            state.vehicles[vid].url = fleet.urls.get(vid, "")
            journal.write("connected", vehicle=vid, url=fleet.urls.get(vid), sysid=v.sysid,
                          autopilot=v.autopilot.name if v.autopilot else None)
        if view is not None:
            view.start(state, fleet)

        async def refresh() -> None:
            while True:
                state.refresh(fleet)
                await asyncio.sleep(0.1)

        refresher = asyncio.create_task(refresh(), name="state refresh")
        executor = Executor(mission, fleet, state, record=journal.write, planner=planner, speedup=scale,
                            clock=clock, write_plan=write_plan)
        if bus is not None:
            bus.attach_executor(executor)
        if command in ("deploy", "run"):
            results["deploy"] = r = await executor.deploy()
            if not r.complete and (command == "deploy" or not r.launched):
                raise ExecutionError("deployment incomplete: tasks not reached: "
                                     + ", ".join(f"{t} ({r.unserved_reasons.get(t, '?')})"
                                                 for t in r.tasks_unserved))
            if r.complete:
                state.event("deployed", f"deployment complete: {len(r.tasks_reached)} tasks reached in "
                            f"{r.flown:.1f} s (planned {r.planned:.1f} s)")
            else:  # run: bring back the rovers that did fly
                state.event("deploy_incomplete", "deployment incomplete: not reached: "
                            + ", ".join(f"{t} ({r.unserved_reasons.get(t, '?')})" for t in r.tasks_unserved)
                            + "; collecting the rovers in the field")
        if command == "run":
            wait = mission.dwell if dwell is None else dwell
            state.set_phase("dwell", wait)
            state.event("dwell", f"dwelling {wait:g} s on task")
            td = clock()
            await executor.sleep_mission(wait)
            dwell_flown = clock() - td
            collect_ids = list(results["deploy"].launched)  # incl. rovers whose task went to a spare
            results["collect"] = r = await executor.collect(collect_ids)
        elif command == "collect":
            results["collect"] = r = await executor.collect()
        if "collect" in results:
            r = results["collect"]
            if not r.complete:
                missing = [x for x in (r.plan.legs() if r.plan else []) if x.rover not in r.rovers_loaded]
                raise ExecutionError("collection incomplete: not loaded: "
                                     + (", ".join(x.rover for x in missing) or "?"))
            state.event("collected", f"collection complete: {len(r.rovers_loaded)} rovers loaded in "
                        f"{r.flown:.1f} s (planned {r.planned:.1f} s)")
        state.phase = "done"
    except ExecutionError as exc:
        error = str(exc)
        state.phase = "failed"
        state.event("error", error)
    except asyncio.CancelledError:
        task = asyncio.current_task()
        if task is not None:
            task.uncancel()
        interrupted = True
        state.phase = "interrupted"
        state.event("interrupted", "interrupted: holding airborne rovers")
        if executor is not None:
            with contextlib.suppress(Exception):
                await executor.hold_airborne()
    finally:
        if refresher is not None:
            refresher.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await refresher
        if executor is not None:
            await executor.close()
        summary = _summary(mission, command, results, state, error, interrupted, journal,
                           dwell_flown)
        summary["schema"] = SUMMARY_SCHEMA
        journal.write("summary", **summary)
        write_summary(summary, journal.summary_path, summary_path)
        if view is not None:
            with contextlib.suppress(Exception):
                await view.stop()
        if fleet is not None:
            with contextlib.suppress(Exception):
                await fleet.close()
        if bus is not None:
            with contextlib.suppress(Exception):
                await bus.aclose(state.phase)
        await journal.aclose()
        if sim_cm is not None:
            with contextlib.suppress(Exception):
                await sim_cm.__aexit__(None, None, None)
    code = EXIT_INTERRUPTED if interrupted else (EXIT_OK if summary["result"] == "complete" else EXIT_FAILED)
    return RunOutcome(code, summary, journal.dir, error)


def _summary(mission: Mission, command: str, results: dict[str, PhaseResult], state: FleetState,
             error: str | None, interrupted: bool, journal: Any, run_dwell: float | None) -> dict[str, Any]:
    dep, col = results.get("deploy"), results.get("collect")
    task_ids = list(dep.tasks_all) if dep is not None and dep.tasks_all else [t.id for t in mission.tasks]
    if command == "collect":
        reached: list[str] = []
        unserved: list[str] = []
    else:
        reached = dep.tasks_reached if dep else []
        unserved = [t for t in task_ids if t not in reached]
    complete = (not interrupted and error is None
                and (command == "collect" or (dep is not None and dep.complete))
                and (command == "deploy" or (col is not None and col.complete)))
    planned: float | None
    flown: float | None
    if command == "deploy":
        planned, flown = (dep.planned, dep.flown) if dep else (None, None)
    elif command == "collect":
        planned, flown = (col.planned, col.flown) if col else (None, None)
    else:  # run: deploy + dwell + collect (planning and uploads between the phases not counted)
        planned = (dep.planned + (mission.dwell if dep else 0.0) + col.planned
                   if dep and col and dep.planned is not None and col.planned is not None else None)
        flown = (dep.flown + (run_dwell or 0.0) + col.flown
                 if complete and dep and col and dep.flown is not None and col.flown is not None else None)
    lost = sorted({*(dep.rovers_lost if dep else []), *(col.rovers_lost if col else [])}
                  - set(col.rovers_loaded if col else []),
                  key=lambda r: list(state.vehicles).index(r) if r in state.vehicles else 0)
    out: dict[str, Any] = {
        "schema": "fleetctl.summary/1",
        "mission": mission.name,
        "phase": command,
        "result": "complete" if complete else ("interrupted" if interrupted else "incomplete"),
        "tasks_reached": reached,
        "tasks_unserved": unserved,
        "rovers_loaded": col.rovers_loaded if col else [],
        "rovers_lost": lost,
        "makespan_planned": None if planned is None else round(planned, 3),
        "makespan_flown": None if flown is None else round(flown, 3),
        "replans": state.replans,
        "journal": str(journal.path),
    }
    out.update(_accounting(command, dep, col, state, task_ids, reached, unserved, lost))
    if col is not None:
        out["rovers_unreachable"] = col.rovers_unreachable
    if dep is not None:
        out["assignment"] = dep.assignment
        out["substitutions"] = dep.substitutions
    if command == "run":
        out["phases"] = {k: {"planned": r.planned, "flown": r.flown, "complete": r.complete}
                         for k, r in results.items()}
    if error is not None:
        out["error"] = error
    return out


__all__ += ["EXIT_FAILED", "EXIT_INTERRUPTED", "EXIT_OK", "RunOutcome", "View", "execute", "sim_mission_dict"]


def _accounting(command: str, dep: PhaseResult | None, col: PhaseResult | None, state: FleetState,
                task_ids: list[str], reached: list[str], unserved: list[str],
                lost: list[str]) -> dict[str, Any]:
    """Summary fields that account for every task and every rover: why a task was not reached
    (``tasks_unserved_reasons``), tasks added/removed while flying, and for each rover not loaded
    nor lost: on the deck, or left in the field at its last known position."""
    out: dict[str, Any] = {"last_replan": state.last_replan}
    if command != "collect":
        reasons = dep.unserved_reasons if dep else {}
        out["tasks_unserved_reasons"] = {t: reasons.get(t, "the deployment did not get to it")
                                         for t in unserved}
        out["tasks_added"] = dep.tasks_added if dep else []
        out["tasks_removed"] = dep.tasks_removed if dep else []
    loaded = set(col.rovers_loaded) if col else set()
    launched = set(dep.launched) if dep else set()
    on_deck: list[str] = []
    left: dict[str, Any] = {}
    last: dict[str, Any] = {}
    for v in state.rovers():
        pos = [round(c, 2) for c in v.enu] if v.enu is not None else None
        if v.id in loaded:
            continue
        if v.id in lost:
            last[v.id] = pos
            continue
        if v.id not in launched and (command != "collect" or v.state in (fs.ON_DECK, fs.REFUSED, fs.UNKNOWN)
                                     and (col is None or v.id not in col.rovers_unreachable)):
            on_deck.append(v.id)
        else:
            left[v.id] = {"position": pos, "state": v.state, "task": v.task}
    out["rovers_on_deck"] = on_deck
    out["rovers_left"] = left
    out["rovers_lost_last_position"] = last
    return out
