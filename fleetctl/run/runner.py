"""One team's flight of ``deploy``, ``collect`` or ``run``: :class:`TeamFlight`, what flies in a
:class:`~fleetctl.run.crew.Crew` of one team (the crew owns the lifecycle: records, clock,
simulated fleet, links, summary, closing).

The flight starts the team's bus, admits the vehicles the links found (preflight, the deck), takes
up a resumed run (:class:`~fleetctl.run.resume.Resumption`: ``fleetctl resume``), flies the phases
(deployment rounds, dwell, collection, or a long operation) and, on its way out, builds the summary
from what the phases saw. Interrupted (Ctrl-C, SIGTERM), it commands airborne rovers to hold. The
run folder (``--run-dir``, default ``runs/<mission>-<timestamp>/``) holds the write-ahead journal,
the ``.tlog``, the plans, the summary and a copy of the mission file.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from typing import TYPE_CHECKING, Any

from fleetctl.aio import cancel_and_wait
from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.link import LinkError
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle
from fleetctl.mission import Mission
from fleetctl.run.admission import Admission, admit
from fleetctl.run.context import ExecutionError
from fleetctl.run.deploy import ResumedDeploy
from fleetctl.run.executor import Executor
from fleetctl.run.kinds import Ev, Phase, VehicleStatus, phases_of
from fleetctl.run.lifecycle import OnSession
from fleetctl.run.results import PhaseResult
from fleetctl.run.rounds import NO_MORE_WORK, DeployRounds, Unserved, WorkSource
from fleetctl.run.state import FleetState
from fleetctl.run.summary import RunFacts, build_summary
from planners.core.plan import Plan
from planners.core.problem import Task

if TYPE_CHECKING:
    from fleetctl.run.crew import Crew

log = logging.getLogger(__name__)


class TeamFlight(OnSession):
    """One team's flight in its crew (see the module docstring)."""

    warm_planners = True  # its first plan is made while rovers may hover

    def __init__(self, crew: Crew[Any]) -> None:
        if crew.opts.teams_resume is not None:
            raise ExecutionError("the records are of a run of several teams and the mission has one carrier")
        self.crew = crew
        self.session = crew.session
        self.mission: Mission = crew.mission
        self.command = crew.command
        self.opts = crew.opts
        self.journal = crew.journal
        self.state = FleetState(self.mission)
        self.state.mission_clock = self.session.clock
        self.results: dict[str, PhaseResult] = {}
        self.deploy_rounds = DeployRounds()
        self.fleet: Fleet | None = None
        self.executor: Executor | None = None
        self.bus: Any = None
        self.dwell_planned: float | None = None
        self.dwell_flown: float | None = None
        self.missing: dict[str, str] = {}  # rovers that did not answer at connect -> why
        self.left_out: dict[str, str] = {}  # rovers that failed preflight -> why
        self._opened = 0.0
        self._refresher: asyncio.Task[None] | None = None

    # ============================================================================== the way in
    def _start_bus(self) -> Any:
        from fleetctl.bus.client import start_bus

        bus = self.opts.bus
        if bus is not None:  # its owner's bus (a team of a teams run): publish this run on it
            self.journal.add_observer(bus.on_record)
            bus.follow(self.state, self.journal.write)
            bus.show_in(self.opts.view)
            return bus
        return start_bus(self.mission, self.opts.mqtt, self.journal, self.state, self.opts.view)

    async def begin(self) -> None:
        """The team's events go to the journal, its bus starts, then the run's first records."""
        self.state.add_listener(self.journal.on_event)
        self.bus = self._start_bus()
        await self.session.begin_records()

    def ready(self) -> None:
        """T+ counts on the simulator's clock once it runs."""
        self.state.mission_clock = self.session.clock
        self.state.phase = Phase.CONNECT
        if self.opts.view is not None:
            self.opts.view.start(self.state, None)
        self._opened = time.monotonic()

    def emit(self, kind: str, text: str, vehicle: str | None = None, **data: Any) -> object:
        return self.state.event(kind, text, vehicle, **data)

    def failed(self, error: str) -> None:
        self.state.phase = Phase.FAILED
        self.state.event(Ev.ERROR, error)

    def _release_batteries(self) -> None:
        """A collection scenario's batteries, held while the fleet connected, drain from now on."""
        self.session.pin_scenario_batteries(False)

    async def connected(self, fleet: Fleet) -> None:
        """Admit the vehicles the links found, take up a resumed run, record the connections."""
        st, view = self.state, self.opts.view
        self.fleet = fleet
        self._refresher = asyncio.create_task(self._refresh(fleet), name="state refresh")
        adm = self._admission()
        self.missing = await admit(fleet, self.mission, self.command, adm)
        for vid, why in self.missing.items():
            st.set_state(vid, VehicleStatus.LOST)
            st.event(Ev.MISSING, f"{fleet.failure_line(vid)}; flying without it", vid,
                     url=fleet.urls.get(vid), reason=why)
        self.left_out = adm.left_out
        if adm.safety is not None and adm.safety.mission is not None:  # fitted to the firmware
            self.mission = adm.safety.mission
        for vid, why in self.left_out.items():  # failed preflight: like a missing rover
            st.set_state(vid, VehicleStatus.LOST)
            st.event(Ev.PREFLIGHT_FAILED, f"{vid}: {why}; flying without it", vid, reason=why)
        for kind, text, vid in adm.safety.notes if adm.safety is not None else ():
            st.event(kind, text, vid)
        self._release_batteries()
        if self.opts.resume is not None:
            await self.opts.resume.reconcile(fleet, st, self._disarm)
            await self.journal.commit(Ev.RESUMED, **self.opts.resume.record())
        for vid, v in fleet.vehicles.items():
            st.vehicles[vid].url = fleet.urls.get(vid, "")
            if not v.connected:
                continue
            self.journal.write(
                Ev.CONNECTED,
                vehicle=vid,
                url=fleet.urls.get(vid),
                sysid=v.sysid,
                autopilot=v.autopilot.name if v.autopilot else None,
            )
        if view is not None:
            view.start(st, fleet)
        resume = self.opts.resume
        self.executor = Executor(
            self.mission,
            fleet,
            st,
            record=self.journal.write,
            commit=self.journal.commit,
            planner=self.opts.planner,
            speedup=self.scale,
            clock=self.clock,
            write_plan=self._write_plan,
            board=resume.board if resume else None,
        )
        if self.bus is not None:
            self.bus.attach_executor(self.executor)

    async def _refresh(self, fleet: Fleet) -> None:
        while True:
            self.state.refresh(fleet)
            await asyncio.sleep(0.1)

    async def _disarm(self, v: Vehicle) -> None:
        await self.journal.commit(Ev.COMMAND, vehicle=v.name, command="disarm")
        try:
            await v.disarm()
        except (CommandRejected, LinkError, TimeoutError) as exc:
            self.state.event(Ev.ROVER_FAILED, f"{v.name}: could not disarm on the deck ({exc})", v.name)

    def _admission(self) -> Admission:
        o = self.opts
        return Admission(require_all=o.require_all, force=o.force, resuming=o.resume is not None,
                         confirm=o.confirm, opened=self._opened)

    def _write_plan(self, kind: str, plan: Plan) -> None:
        name = "plan.json" if kind == "deploy" or self.command == "collect" else "plan-collect.json"
        self.journal.write_json(name, plan.to_json())
        self._export(plan, "export" if name == "plan.json" else "export-collect")

    def _export(self, plan: Plan, folder: str) -> None:
        """RUN/export/: the uploaded mission items as QGroundControl plans, and plan.geojson."""
        if self.executor is None or self.fleet is None or self.mission.origin is None:
            return
        from fleetctl.mission.formats.plan_export import export_plan

        try:
            compiled = self.executor.planning.compile(plan)
            aps = {vid: v.autopilot for vid, v in self.fleet.vehicles.items() if v.autopilot is not None}
            export_plan(self.mission, plan, compiled, self.journal.dir / folder, autopilots=aps, prune=True)
        except (ExecutionError, OSError, ValueError) as exc:  # the records must never stop a flight
            log.warning("could not write %s/: %s", folder, exc)

    # ============================================================================== the phases
    async def phases(self) -> None:
        resume = self.opts.resume
        todo = (["operation"] if self.mission.operation else resume.phases_left(self.command)
                if resume is not None else phases_of(self.command))
        if resume is not None:
            self.results.update(resume.finished_results())
        for phase in todo:
            await self.journal.commit(Ev.PHASE, phase=phase)
            if phase == "operation":
                await self._operation()
            elif phase == "deploy":
                await self._deploy()
            elif phase == "dwell":
                await self._dwell()
            else:
                await self._collect()
        self.state.phase = Phase.DONE

    async def _deploy(self) -> None:
        """The deployment: a first round flies the mission's tasks, then one more round per batch
        the work source hands over (:mod:`fleetctl.run.rounds`; a one-carrier run has none)."""
        assert self.executor is not None
        source, resume = self._work_source(), self.opts.resume
        if self.mission.tasks or source.flies_empty_share:
            r = await self._deploy_round(source, resume.deploy if resume is not None else None)
        else:  # a team that was given no task (yet) stands by for handed-over work
            r = self.results["deploy"] = PhaseResult("deploy", complete=True)
        while (tasks := await source.next_round(r)) is not None:
            self._hand_over(source, tasks)
            r = await self._deploy_round(source, None)
        if source.unserved is Unserved.HAND_BACK:
            self._judge_deploy(r)

    def _work_source(self) -> WorkSource:
        """Who hands this deployment more rounds (a several-carrier team's run: the other teams)."""
        return NO_MORE_WORK

    async def _deploy_round(self, source: WorkSource, resumed: ResumedDeploy | None) -> PhaseResult:
        assert self.executor is not None
        r = await self.executor.deploy(resumed)
        self.deploy_rounds.count(r)
        self._round_flown(r)
        if source.unserved is Unserved.FAIL:
            self._judge_deploy(r)
        return r

    def _round_flown(self, result: PhaseResult) -> None:
        """After each deployment round, before the work source is asked for more (a hook)."""

    def _hand_over(self, source: WorkSource, tasks: list[Task]) -> None:
        """Tasks the source hands over for one more round go on the board."""
        assert self.executor is not None
        for t in tasks:
            self.executor.board.add(t)
        if tasks:
            ids = [t.id for t in tasks]
            self.state.event(Ev.HANDOVER, f"{source.name}: another deployment round for handed-over "
                             f"task(s) {', '.join(ids)}", None, tasks=ids)

    def _judge_deploy(self, r: PhaseResult) -> None:
        """A deployment's result: the run's, an event, and ExecutionError when it cannot go on."""
        self.results["deploy"] = r
        reasons = ", ".join(f"{t} ({r.unserved_reasons.get(t, '?')})" for t in r.tasks_unserved)
        if not r.complete and (self.command == "deploy" or not r.launched):
            raise ExecutionError("deployment incomplete: tasks not reached: " + reasons)
        if r.complete:
            self.state.event(
                Ev.DEPLOYED,
                f"deployment complete: {len(r.tasks_reached)} tasks reached in {r.flown or 0.0:.1f} s"
                + (f" (planned {r.planned:.1f} s)" if r.planned is not None else " (nothing left to plan)"),
            )
        else:  # run: bring back the rovers that did fly
            self.state.event(
                Ev.DEPLOY_INCOMPLETE,
                f"deployment incomplete: not reached: {reasons}; collecting the rovers in the field",
            )

    async def _dwell(self) -> None:
        assert self.executor is not None
        resume = self.opts.resume
        wait = self.mission.dwell if self.opts.dwell is None else self.opts.dwell
        self.dwell_planned = wait
        left = resume.dwell_left(wait) if resume is not None else wait
        self.state.set_phase(Phase.DWELL, wait)
        self.state.event(Ev.DWELL, f"dwelling {left:g} s on task")
        td = self.clock()
        await self.executor.sleep_mission(left)
        self.dwell_flown = (wait - left) + (self.clock() - td)

    async def _operation(self) -> None:
        """A long operation (docs/operations.md): one phase of sorties, pick-ups and swaps."""
        assert self.executor is not None
        resume = self.opts.resume
        r = await self.executor.operate(self._write_operation_plan,
                                        resume.operation if resume is not None else None)
        self.results["operation"] = r
        if not r.complete:
            lost = f"; rovers lost: {', '.join(r.rovers_lost)}" if r.rovers_lost else ""
            left = ", ".join(r.tasks_unserved) or "none"
            raise ExecutionError(f"operation incomplete: work not done: {left}{lost}")
        await self.executor.carrier.park()

    def _write_operation_plan(self, name: str, plan: dict[str, Any]) -> None:
        self.journal.write_json(name, plan)

    async def _collect(self) -> None:
        assert self.executor is not None
        resume = self.opts.resume
        ids: list[str] | None = None
        if resume is not None:
            ids = resume.collect_ids()
        elif self.command == "run":
            ids = list(self.results["deploy"].launched)  # incl. rovers whose task went to a spare
        r = await self.executor.collect(ids, resume.collect if resume is not None else None)
        self.results["collect"] = r
        if not r.complete:
            missing = [x for x in (r.plan.legs() if r.plan else []) if x.rover not in r.rovers_loaded]
            raise ExecutionError(
                "collection incomplete: not loaded: " + (", ".join(x.rover for x in missing) or "?")
            )
        self.state.event(
            Ev.COLLECTED,
            f"collection complete: {len(r.rovers_loaded)} rovers loaded in "
            f"{r.flown:.1f} s (planned {r.planned:.1f} s)",
        )

    # ============================================================================== the way out
    async def cancelled(self) -> None:
        self.state.phase = Phase.INTERRUPTED
        self.state.event(Ev.INTERRUPTED, "interrupted: holding airborne rovers")
        if self.executor is not None:
            with contextlib.suppress(Exception):
                await self.executor.hold_airborne()

    def _snapshot_results(self) -> None:
        """After an interruption or failure: what each running phase saw so far."""
        ex = self.executor
        if ex is None:
            return
        if ex.deploy_phase is not None and "deploy" not in self.results:
            self.results["deploy"] = ex.deploy_phase.snapshot()
        if ex.operation_phase is not None and "operation" not in self.results:
            self.results["operation"] = ex.operation_phase.snapshot()
        if ex.collect_phase is not None and "collect" not in self.results:
            self.results["collect"] = ex.collect_phase.snapshot()

    async def end(self) -> dict[str, Any]:
        await cancel_and_wait(self._refresher)
        if self.fleet is not None:
            self.state.refresh(self.fleet)
        self._snapshot_results()
        if self.executor is not None:
            await self.executor.close()
        summary = build_summary(
            RunFacts(
                self.mission,
                self.command,
                self.results,
                self.state,
                self.error,
                self.interrupted,
                str(self.journal.path),
                self.dwell_planned,
                self.dwell_flown,
                self.missing,
                self.left_out,
                mqtt=self.bus.stats() if self.bus is not None else None,
            )
        )
        return summary

    async def close_bus(self) -> None:
        if self.bus is None:
            return
        if self.opts.bus is None:
            await self.bus.aclose(self.state.phase)
        else:  # its owner closes it
            await self.bus.unfollow()


__all__ = ["TeamFlight"]
