"""Execution state machines: fly a deployment and a collection over MAVLink.

:class:`Executor` works on a connected :class:`fleetctl.vehicle.Fleet` and writes what happens
into a :class:`fleetctl.fleet.FleetState` (read by the dashboard) and the journal.

Deployment: plan with the mission's planner from the carrier's live position and heading, upload
the carrier's route (:mod:`fleetctl.compile`: a waypoint and an unlimited loiter per stop) and the
rovers' missions (take-off to task height, waypoint(s) to the task, loiter), start the carrier,
then stop by stop: wait for the carrier to arrive, launch that stop's rovers (any rover on the
deck may take any task; one that refuses to arm is skipped and a spare takes its task), wait
until they are off the deck and ``unload_time`` has passed, release the carrier. A task is
*reached* when its rover holds within :data:`REACH_RADIUS` of it.

Collection: read every rover's position and battery, derive ranges (:mod:`fleetctl.energy`),
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

from fleetctl import fleet as fs
from fleetctl.compile import CompiledPlan, CompileError, RoverMission, compile_for_fleet
from fleetctl.energy import range_from_percent
from fleetctl.fleet import FleetState, on_deck
from fleetctl.link import LinkError, MissionItem, MissionRejected
from fleetctl.mission import Mission
from fleetctl.vehicle import CommandRejected, Fleet, Vehicle, VehicleEvent
from planners.plan import Plan
from planners.problem import CollectRover, PlanningError

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
        """Run one command, journaling it and its ack."""
        self.record("command", vehicle=v.name, command=what, **data)
        try:
            result = await aw
        except CommandRejected as exc:
            self.record("ack", vehicle=v.name, command=what, result=exc.ack.result_name, reason=exc.reason)
            raise
        except MissionRejected as exc:
            self.record("ack", vehicle=v.name, command=what, result=exc.result_name)
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
        cfg = self.mission.planner
        given = None
        if self.planner:  # "NAME" for both phases, or "DEPLOY,COLLECT" (fleetctl run)
            parts = [p.strip() for p in self.planner.split(",")]
            given = parts[0] if kind == "deploy" else parts[-1]
        name = given or (cfg.deploy if kind == "deploy" else cfg.collect)
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
            raise ExecutionError(f"{v.name} ({self.fleet.urls.get(v.name, '')}) rejected its mission: "
                                 f"{exc.result_name}") from None

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

    # ============================================================================== deployment
    async def deploy(self) -> PhaseResult:
        """Plan from the live state and fly the deployment; returns what was reached."""
        res = PhaseResult("deploy")
        st = self.state
        st.set_phase("plan")
        await self._wait_telemetry()
        rovers = self.rovers()
        deck = [rid for rid, v in rovers.items() if self.rover_on_deck(v)]
        for rid, v in rovers.items():
            away = fs.LOST if not v.connected or v.lost else fs.LANDED
            st.set_state(rid, fs.ON_DECK if rid in deck else away)
        tasks = self.mission.tasks
        if len(deck) < len(tasks):
            raise ExecutionError(f"{len(deck)} rover(s) on the carrier's deck ({', '.join(deck) or 'none'}) "
                                 f"for {len(tasks)} tasks: every task needs a rover on the deck")
        start, heading = self.carrier_pose()
        problem = dataclasses.replace(self.mission.deploy_problem(), start=start, heading=heading,
                                      rovers=tuple(deck))
        plan = await self._plan("deploy", problem)
        res.plan, res.planned = plan, plan.makespan
        compiled = self._compile(plan)
        slots = compiled.rovers  # planned rover id -> its mission (the rover actually flying may differ)
        spares = [rid for rid in deck if rid not in slots]
        self.record("spares", rovers=spares)

        # upload every planned rover's mission while nothing moves yet
        uploaded: dict[str, str] = {}  # rover -> slot whose mission it holds

        async def pre_upload(slot: RoverMission) -> None:
            v = rovers[slot.rover]
            try:
                await self._upload(v, list(slot.items))
                uploaded[slot.rover] = slot.rover
            except (ExecutionError, LinkError, TimeoutError) as exc:
                log.warning("%s: upload failed (%s); a spare will fly %s", v.name, exc, slot.task)

        st.set_phase("deploy", plan.makespan, len(plan.stops))
        await asyncio.gather(*(pre_upload(s) for s in slots.values()))
        await self._start_carrier(compiled)
        t0 = self.clock()
        res.started = t0
        st.phase_started = t0
        self.state.event("carrier_started", f"{self.fleet.carrier.name}: route started "
                         f"({len(plan.stops)} stops)", self.fleet.carrier.name)

        reached: dict[str, float] = {}
        watchers: list[asyncio.Task[None]] = []
        used: set[str] = set(slots)

        def take_spare() -> str | None:
            for rid in spares:
                r = rovers[rid]
                if rid not in used and rid not in self.refused and r.connected and not r.lost:
                    used.add(rid)
                    return rid
            return None

        async def launch(slot: RoverMission) -> None:
            rid: str | None = slot.rover
            while rid is not None:
                v = rovers[rid]
                if not self.rover_on_deck(v):  # telemetry of rover and carrier may be of different moments
                    with contextlib.suppress(TimeoutError):
                        await v.wait_until(self.rover_on_deck, DECK_CHECK_TIMEOUT, "on the deck")
                if not self.rover_on_deck(v):
                    st.event("rover_skipped", f"{rid}: not on the deck, a spare takes {slot.task}", rid)
                    rid = take_spare()
                    continue
                try:
                    if uploaded.get(rid) != slot.rover:
                        await self._upload(v, list(slot.items))
                        uploaded[rid] = slot.rover
                    await self._do(v, "arm", v.arm())
                except CommandRejected as exc:
                    self.refused.add(rid)
                    st.set_state(rid, fs.REFUSED)
                    spare = take_spare()
                    reason = exc.reason or exc.ack.result_name
                    then = f"spare {spare} takes {slot.task}" if spare else f"no spare left for {slot.task}"
                    st.event("rover_refused", f"{rid}: refused to arm ({reason}); {then}",
                             rid, reason=reason, spare=spare, task=slot.task)
                    if spare is not None:
                        res.substitutions.append({"refused": rid, "spare": spare, "task": slot.task or ""})
                    rid = spare
                    continue
                except (ExecutionError, LinkError, TimeoutError) as exc:
                    spare = take_spare()
                    st.event("rover_failed", f"{rid}: {exc}; " + (f"spare {spare} takes {slot.task}" if spare
                                                                    else f"no spare left for {slot.task}"),
                             rid, spare=spare, task=slot.task)
                    rid = spare
                    continue
                try:
                    await self._do(v, "start_mission", v.start_mission())
                    tk = _takeoff_seq(slot)
                    await v.wait_until(  # a task on the ground may be left again before a position shows it
                        lambda v, tk=tk: ((v.relative_alt or 0.0) > AIRBORNE_HEIGHT or tk in v.items_reached
                                          or (v.mission_current or -1) > tk),
                        self.wall(5.0), "lift-off")
                except (CommandRejected, LinkError, TimeoutError) as exc:
                    st.event("rover_failed", f"{rid}: did not take off ({exc})", rid, task=slot.task)
                    with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
                        await v.disarm()
                    rid = take_spare()
                    continue
                res.assignment[slot.task or ""] = rid
                st.set_state(rid, fs.CLIMBING, task=slot.task)
                st.event("rover_launched", f"{rid}: launched for {slot.task} at stop {slot.stop + 1}", rid,
                         task=slot.task, stop=slot.stop + 1)
                watchers.append(self._spawn(watch(rid, slot), f"watch {rid}"))
                return
            st.event("task_unserved", f"{slot.task}: no rover left to fly it", None, task=slot.task)

        async def watch(rid: str, slot: RoverMission) -> None:
            v = rovers[rid]
            leg = next(leg for s in plan.stops for leg in s.rovers if leg.rover == slot.rover)
            target = leg.end
            takeoff_seq = _takeoff_seq(slot)

            def check(v: Vehicle) -> bool:
                if st.vehicles[rid].state == fs.CLIMBING and (v.mission_current or 0) > takeoff_seq:
                    st.set_state(rid, fs.EN_ROUTE)
                p = v.enu
                return (p is not None and math.dist(p, target) <= REACH_RADIUS
                        and (v.ground_speed or 0.0) < HOLD_SPEED)

            remaining = max(leg.arrive - (self.clock() - t0), 0.0)
            try:
                await v.wait_until(check, self.wall(remaining), f"task {slot.task}")
            except TimeoutError:
                st.event("task_timeout", f"{rid}: did not reach {slot.task} in time", rid, task=slot.task)
                return
            reached[slot.task or ""] = self.clock() - t0
            st.set_state(rid, fs.ON_TASK)
            st.event("task_reached", f"{rid}: reached {slot.task} "
                     f"(at {reached[slot.task or '']:.1f} s, planned {leg.arrive:.1f} s)", rid,
                     task=slot.task, flown=reached[slot.task or ""], planned=leg.arrive)

        prev = 0.0
        for k, (stop, items) in enumerate(zip(plan.stops, compiled.stops, strict=True)):
            arrived = await self._wait_stop(k, items.arrive_seq, stop.arrive - prev)
            prev = stop.depart
            launches = [launch(slots[leg.rover]) for leg in stop.rovers]
            unload = self.sleep_mission(max(arrived + self.mission.carrier.unload_time - self.clock(), 0.0))
            await asyncio.gather(unload, *launches)
            await self._release_carrier(items.release_seq)
            if items.release_seq is not None:
                self.record("carrier_released", stop=k + 1)
        self.state.set_state(self.fleet.carrier.name, fs.IDLE)
        if watchers:
            await asyncio.gather(*watchers, return_exceptions=True)
        res.tasks_reached = sorted(reached, key=lambda t: [x.id for x in tasks].index(t))
        res.tasks_unserved = [t.id for t in tasks if t.id not in reached]
        res.rovers_lost = [rid for rid, v in rovers.items() if v.lost]
        res.complete = not res.tasks_unserved
        if res.complete:
            res.flown = max(reached.values())
        return res

    # ============================================================================== collection
    async def collect(self, rover_ids: Iterable[str] | None = None) -> PhaseResult:
        """Plan the collection from live positions and batteries and fly it.

        ``rover_ids``: the rovers to collect (default: every connected rover not on the deck)."""
        res = PhaseResult("collect")
        st = self.state
        st.set_phase("plan")
        await self._wait_telemetry()
        rovers = self.rovers()
        ids = list(rover_ids) if rover_ids is not None else [
            rid for rid, v in rovers.items() if v.connected and not self.rover_on_deck(v)]
        lost = [rid for rid in ids
                if not rovers[rid].connected or rovers[rid].lost or rovers[rid].enu is None]
        res.rovers_lost = lost
        for rid in lost:
            st.set_state(rid, fs.LOST)
        live = [rid for rid in ids if rid not in lost]
        if not live:
            res.complete = not lost
            res.planned = res.flown = 0.0
            st.event("nothing_to_collect", "no rover to collect" + (f" ({len(lost)} lost)" if lost else ""))
            return res
        rp = self.mission.rovers
        crs = []
        for rid in live:
            v = rovers[rid]
            p = v.enu
            assert p is not None
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
        live = [rid for rid in live if rid not in res.rovers_unreachable]
        if not live:
            res.complete, res.planned, res.flown = True, 0.0, 0.0
            return res
        start, heading = self.carrier_pose()
        from planners.problem import CollectProblem

        problem = CollectProblem(self.mission.carrier.spec(), rp.motion(), start, heading, tuple(crs))
        plan = await self._plan("collect", problem)
        res.plan, res.planned = plan, plan.makespan
        compiled = self._compile(plan)

        # each rover holds above its meeting point until the carrier is there, then lands
        land_seq: dict[str, int] = {}
        hold_seq: dict[str, int] = {}
        items_of: dict[str, list[MissionItem]] = {}
        for rid, rm in compiled.rovers.items():
            items = list(rm.items)
            hold = dataclasses.replace(items[rm.target_seq], command=M.MAV_CMD_NAV_LOITER_UNLIM)
            items.insert(rm.target_seq + 1, hold)
            hold_seq[rid], land_seq[rid] = rm.target_seq + 1, rm.final_seq + 1
            items_of[rid] = items

        st.set_phase("collect", plan.makespan, len(plan.stops))
        results = await asyncio.gather(*(self._upload(rovers[rid], items) for rid, items in items_of.items()),
                                       return_exceptions=True)
        failed = {rid: r for rid, r in zip(items_of, results, strict=True) if isinstance(r, BaseException)}
        for rid, exc in failed.items():
            st.event("rover_failed", f"{rid}: mission upload failed ({exc})", rid)
        await self._start_carrier(compiled)
        t0 = self.clock()
        res.started = t0
        st.phase_started = t0

        async def go(rid: str) -> None:
            v = rovers[rid]
            try:
                if not v.armed:
                    await self._do(v, "arm", v.arm())
                await self._do(v, "start_mission", v.start_mission())
                st.set_state(rid, fs.RETURNING)
            except (CommandRejected, LinkError, TimeoutError) as exc:
                st.event("rover_failed", f"{rid}: cannot start its way back ({exc})", rid)
                failed[rid] = exc

        await asyncio.gather(*(go(rid) for rid in items_of if rid not in failed))
        st.event("collection_started", f"collecting {len(items_of) - len(failed)} rovers", None)
        loaded: dict[str, float] = {}

        async def bring_in(rid: str, leg_arrive: float) -> None:
            v = rovers[rid]
            if rid in failed:
                return
            try:
                await v.wait_until(
                    lambda v: (v.mission_current or 0) >= hold_seq[rid] or self.rover_on_deck(v),
                    self.wall(max(leg_arrive - (self.clock() - t0), 0.0)), "meeting point")
                if not self.rover_on_deck(v):
                    await self._do(v, "set_current", v.set_current(land_seq[rid]), seq=land_seq[rid])
                    st.set_state(rid, fs.LANDED)
                await v.wait_until(self.rover_on_deck, self.wall(10.0), "landing on the carrier")
            except (CommandRejected, LinkError, TimeoutError) as exc:
                st.event("rover_failed", f"{rid}: not loaded ({exc})", rid)
                return
            loaded[rid] = self.clock() - t0
            st.set_state(rid, fs.LOADED)
            st.event("rover_loaded", f"{rid}: loaded on the carrier at {loaded[rid]:.1f} s", rid,
                     flown=loaded[rid])

        prev = 0.0
        last_load = t0
        for k, (stop, items) in enumerate(zip(plan.stops, compiled.stops, strict=True)):
            await self._wait_stop(k, items.arrive_seq, stop.arrive - prev)
            prev = stop.depart
            await asyncio.gather(*(bring_in(leg.rover, leg.arrive) for leg in stop.rovers))
            await self.sleep_mission(self.mission.carrier.load_time)
            last_load = self.clock()
            await self._release_carrier(items.release_seq)
            if items.release_seq is not None:
                self.record("carrier_released", stop=k + 1)
        self.state.set_state(self.fleet.carrier.name, fs.IDLE)
        res.rovers_loaded = [rid for rid in live if rid in loaded]
        res.rovers_lost = lost + [rid for rid in live if rid not in loaded and rovers[rid].lost]
        res.complete = len(res.rovers_loaded) == len(live)
        res.flown = last_load - t0 if res.complete else None
        return res

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
    """What the runner shows while flying (:mod:`fleetctl.dashboard` implements it)."""

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
) -> RunOutcome:
    """Fly ``command`` (``deploy`` | ``collect`` | ``run``) of ``mission`` end to end: start the
    embedded simulator for ``connection: sim``, connect, fly, and write the records. Cancelling
    the task (Ctrl-C) commands airborne rovers to hold, writes journal and summary and returns
    exit code 130.

    ``sim``: an already running ``sitl.SimFleet`` to fly against (its endpoints, its simulated clock
    and speedup; tests and benchmarks use it to look at the simulated world). ``on_sim`` is called
    with the embedded simulator once it runs. ``clock_speedup``: vehicles that run that much faster
    than the wall clock elsewhere (a simulator in another process): mission time = wall x it."""
    from fleetctl.journal import SUMMARY_SCHEMA, Journal, run_dir_for, write_summary
    from fleetctl.vehicle import FleetConnectError, connect_fleet

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
        if command in ("deploy", "run"):
            results["deploy"] = r = await executor.deploy()
            if not r.complete:
                raise ExecutionError("deployment incomplete: tasks not reached: "
                                     + ", ".join(r.tasks_unserved))
            state.event("deployed", f"deployment complete: {len(r.tasks_reached)} tasks reached in "
                        f"{r.flown:.1f} s (planned {r.planned:.1f} s)")
        if command == "run":
            wait = mission.dwell if dwell is None else dwell
            state.set_phase("dwell", wait)
            state.event("dwell", f"dwelling {wait:g} s on task")
            td = clock()
            await executor.sleep_mission(wait)
            dwell_flown = clock() - td
            collect_ids = list(results["deploy"].assignment.values())
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
        await journal.aclose()
        if sim_cm is not None:
            with contextlib.suppress(Exception):
                await sim_cm.__aexit__(None, None, None)
    code = EXIT_INTERRUPTED if interrupted else (EXIT_OK if summary["result"] == "complete" else EXIT_FAILED)
    return RunOutcome(code, summary, journal.dir, error)


def _summary(mission: Mission, command: str, results: dict[str, PhaseResult], state: FleetState,
             error: str | None, interrupted: bool, journal: Any, run_dwell: float | None) -> dict[str, Any]:
    dep, col = results.get("deploy"), results.get("collect")
    task_ids = [t.id for t in mission.tasks]
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
    lost = sorted({*(dep.rovers_lost if dep else []), *(col.rovers_lost if col else [])},
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
        "replans": 0,
        "journal": str(journal.path),
    }
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
