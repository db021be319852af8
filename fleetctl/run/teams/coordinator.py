"""``deploy``, ``collect`` and ``run`` of a mission with several carriers, in one controller.

:class:`TeamsFlight` is what flies in the :class:`~fleetctl.run.crew.Crew` of such a mission (the
crew owns the lifecycle: one simulated fleet serving every carrier for ``connection: sim``, the
links of every vehicle opened once, the records, the summary). It shares the work between the
teams with ``planners.teams`` (from the carriers' live poses) and flies each team concurrently as a
crew of one team (:func:`~fleetctl.run.teams.team_run.team_crew`) on its share, on its own view
of the fleet, with its own records in ``RUN/teams/<carrier>/<phase>/``. ``run`` deploys every
team, dwells, then shares the collection out again from the rovers' live positions and batteries:
a rover may land on another team's carrier.

Cross-team replanning (:class:`~fleetctl.run.teams.handover.Handovers`): a team whose carrier
stays lost longer than ``links.reassign_after`` hands its unlaunched tasks over, and a team
that ends its deployment with tasks unserved (no usable rover left, timeouts) or whose run
fails hands those; the receiving teams are chosen by planning the handed tasks over the teams
that can still take them (the time model), and get them as a task change while they deploy or
as a further deployment round once they finished. The run's own records (``RUN/journal.jsonl``,
``RUN/traffic*.tlog``, one per link, ``RUN/plan.json``, ``RUN/summary.json``) combine the teams.
With an MQTT bus every team publishes under ``P/teams/<carrier>`` and the run under ``P``
(:mod:`fleetctl.run.teams.bus`).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from fleetctl.aio import cancel_and_wait
from fleetctl.mavlink.fleet import Fleet
from fleetctl.mission import Mission
from fleetctl.mission.teams import mission_teams, team_mission, teams_problem
from fleetctl.run.context import ExecutionError
from fleetctl.run.crew import Crew
from fleetctl.run.kinds import Ev, phases_of
from fleetctl.run.lifecycle import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, OnSession, RunOptions, RunOutcome
from fleetctl.run.results import PhaseResult
from fleetctl.run.resume import Resumption
from fleetctl.run.resume_teams import TeamsResumption, team_folder
from fleetctl.run.teams.board import ACTIVE, Handover, TeamEntry, TeamsBoard, TeamStatus
from fleetctl.run.teams.bus import TeamsBuses
from fleetctl.run.teams.handover import Handovers
from fleetctl.run.teams.live import live_mission, rovers_in_the_field
from fleetctl.run.teams.summary import teams_summary
from fleetctl.run.teams.team_run import TeamRun, team_crew
from fleetctl.run.teams.views import team_views
from fleetctl.run.vehicle_events import battery_low_text, tell_vehicle_event
from fleetctl.teams_plan import share_teams
from planners.core.problem import CollectRover, Task
from planners.teams import TeamsPlan

log = logging.getLogger(__name__)

WATCH_EVERY = 0.2  # wall s between looks at the carriers' links while the teams deploy
CLOCK_STEP = 0.05  # wall s between looks at the mission clock while dwelling


class TeamsFlight(OnSession):
    """The flight of several teams in their crew (see the module docstring)."""

    warm_planners = False  # each team's crew warms its own

    def __init__(self, crew: Crew[Any]) -> None:
        mission, opts = crew.mission, crew.opts
        if opts.resume is not None:
            raise ExecutionError("the records are of a run of one carrier and the mission has several")
        self.resume = opts.teams_resume  # a run of several teams to finish (fleetctl.run.resume_teams)
        self.session = crew.session
        self.mission = mission
        self.command = crew.command
        self.opts = opts
        self.journal = crew.journal
        self.board = TeamsBoard(
            {t.carrier.id: TeamEntry(t.carrier.id, t.rovers) for t in mission_teams(mission)}
        )
        self.fleet: Fleet | None = None
        self.runs: dict[str, dict[str, TeamRun]] = {}  # phase -> team -> its run
        self.flying: dict[str, asyncio.Task[RunOutcome]] = {}  # team -> its run of the phase flying
        self._stopped: set[str] = set()  # lost teams whose run was stopped
        self.outcomes: dict[str, dict[str, RunOutcome]] = {}  # phase -> team -> its outcome
        self.plans: dict[str, TeamsPlan] = {}  # phase -> how the work was shared
        self.handovers = Handovers(self)
        self.views: dict[str, Any] = {}  # team -> its view of the phase flying (fleetctl.run.teams.views)
        self.left: dict[str, str] = {}  # run: launched rovers the collection leaves in the field -> why
        self.deployed_before = False  # resumed past the deployment: it was flown before the restart
        self.loaded_before: list[str] = []  # resumed collection: rovers loaded before the restart
        self.dwell_planned: float | None = None
        self.dwell_flown: float | None = None
        self.t0 = 0.0  # mission clock when the run of every team started (T+ = 0)
        self.summary: dict[str, Any] = {}  # once built on the way out
        self._confirm_lock = threading.Lock()
        self._low: set[str] = set()  # rovers told at their reserve while dwelling
        self.buses = TeamsBuses.configure(mission, opts.mqtt, self.journal.write,
                                          "sim" if self.session.uses_sim else "real")

    # ============================================================================== the way in
    async def begin(self) -> None:
        """The ``run`` record names every team; then the buses (the run's and each team's) start."""
        teams = {cid: list(e.rovers) for cid, e in self.board.teams.items()}
        await self.session.begin_records(teams=teams)
        self.journal.add_observer(self.buses.on_record)
        self.buses.start(list(self.board.teams))

    def ready(self) -> None:
        """T+ = 0 for every team (each team's crew lets a collection scenario's batteries drain)."""
        self.t0 = self.clock()

    async def connected(self, fleet: Fleet) -> None:
        """Every vehicle of every team on one set of links (each team flies a view of it)."""
        self.fleet = fleet
        for vid, v in fleet.vehicles.items():
            if v.connected:
                self.journal.write(Ev.CONNECTED, vehicle=vid, url=fleet.urls.get(vid), sysid=v.sysid)
        if self.resume is not None:
            self._resumed_records(self.resume)
            await self.journal.commit(Ev.RESUMED, **self.resume.record())

    async def phases(self) -> None:
        for phase in self._phases():
            if phase == "deploy":
                await self._deploy()
            elif phase == "dwell":
                await self._dwell()
            else:
                await self._collect()

    def failed(self, error: str) -> None:
        self.journal.write(Ev.ERROR, text=error)

    async def cancelled(self) -> None:
        """Each team's run, cancelled with this one, holds its own airborne rovers."""
        self.journal.write(Ev.INTERRUPTED, text="interrupted: every team holds its airborne rovers")

    def _phases(self) -> list[str]:
        if self.resume is not None:
            return self.resume.phases_left()
        return phases_of(self.command)

    def _resumed_records(self, resume: TeamsResumption) -> None:
        """A resumed run: the hand-overs recorded before the restart stand (a task handed to a team
        is that team's, never handed back to the team that gave it up, a team whose carrier was
        lost stays lost); past the deployment, what it reached counts and the rovers already
        loaded stay loaded."""
        board, now = self.board, time.time()
        by_id = {t.id: t for t in self.mission.tasks}
        for cid, tasks in (resume.shares or {}).items():
            if cid in board.teams:
                board.allocate(cid, tasks)
        board.owner.update(resume.owner())
        board.gave_up.update(resume.gave_up())
        for cid in resume.lost:  # a team whose carrier was lost takes no more tasks
            if cid in board.teams:
                board.teams[cid].lost = True
        if resume.phase == "deploy":
            self._ended_deployments(resume)
        for h in resume.handovers:  # T before the resumed run's start: negative
            board.handovers.append(Handover(h.tasks, h.from_team, h.to_team, h.why,
                                            self.t0 - max(0.0, now - h.t) * self.scale))
            if h.to_team in board.teams:
                board.teams[h.to_team].received.extend(by_id[t] for t in h.tasks if t in by_id)
        if resume.phase != "deploy":
            self.deployed_before = resume.command == "run"  # a collect run has no deployment
            for tid, (cid, _) in resume.reached().items():
                board.reached.setdefault(tid, (cid, self.t0))
            for entry in board.teams.values():
                entry.status, entry.finished = TeamStatus.DONE, True
            self.loaded_before = resume.loaded()

    def _ended_deployments(self, resume: TeamsResumption) -> None:
        """Teams whose deployment run was over before the kill (a carrier that failed its preflight,
        a team with nothing left) stay over: what they reached counts, their run's summary stands,
        and they are not flown again nor handed tasks."""
        board = self.board
        reached = resume.reached()
        for cid in resume.deploy_ended:
            if cid not in board.teams:
                continue
            for tid, (team, _) in reached.items():
                if team == cid:
                    board.reached.setdefault(tid, (cid, self.t0))
            summary = resume.deploy_summary(cid)
            result = str(summary.get("result") or resume.deploy_ended[cid])
            self.outcomes.setdefault("deploy", {})[cid] = RunOutcome(
                EXIT_OK if result == "complete" else EXIT_FAILED, summary,
                team_folder(resume.run_dir, cid, "deploy"), summary.get("error"))
            board.teams[cid].finished = True
            board.set_status(cid, TeamStatus.FAILED if board.owned_unreached(cid) else TeamStatus.DONE)

    def emit(self, kind: str, text: str, vehicle: str | None = None, **data: Any) -> None:
        """An event of the run of every team (its journal: the teams' views show their own)."""
        self.journal.write(kind, vehicle=vehicle, text=text, **data)

    # ============================================================================== deployment
    async def _deploy(self) -> None:
        resume = self.resume if self.resume is not None and self.resume.shares is not None else None
        if resume is None:  # a new deployment (or one killed before its work was shared)
            plan = await self._share("deploy", self.live_mission())
            for team in plan.teams:
                tasks = [leg.task for leg in team.plan.legs() if leg.task is not None]
                self.board.allocate(team.carrier, tasks)
        else:
            self.buses.start_teams({cid: resume.team_tasks(cid) for cid in self.board.teams})
        self.views = team_views(self.opts.view, list(self.board.teams))
        runs = {
            cid: team_crew(
                self._team_mission(cid, tasks=resume.team_tasks(cid) if resume is not None else e.tasks),
                "deploy",
                self._team_opts(cid, "deploy", resume=None if resume is None else resume.team_deploy(cid)),
                cid,
                self,
                self.t0,
            ).flight
            for cid, e in self.board.teams.items()
            if resume is None or cid not in resume.deploy_ended  # a deployment over before the kill: over
        }
        self.runs["deploy"] = runs
        for cid in runs:
            self.board.set_status(cid, TeamStatus.DEPLOYING)
        watch = asyncio.create_task(self._watch_carriers(), name="teams: carrier watch")
        try:
            await self._fly_all("deploy", runs, self._deploy_ended)
        finally:
            await cancel_and_wait(watch)

    async def _deploy_ended(self, cid: str, run: TeamRun, outcome: RunOutcome) -> None:
        """A team's deployment run is over: what it reached counts; what it owns and did not reach
        goes to teams that can still take it."""
        self._note_reached(cid, run)
        left = self.board.owned_unreached(cid)
        if left and self.board.teams[cid].status != TeamStatus.SETTLING:
            why = outcome.error or "its run ended"
            await self.handovers.place(self._task_objects(run, left), cid, f"{cid}: {why}")
        self.board.set_status(cid, TeamStatus.FAILED if self.board.owned_unreached(cid) else TeamStatus.DONE)

    async def more_work(self, team: str, result: PhaseResult) -> list[Task]:
        """Asked by a team's run after each deployment round: hand its unserved tasks over, then
        wait until it is handed tasks (returned: one more round) or no team can hand any over
        (``[]``: its deployment is over)."""
        entry, run = self.board.teams[team], self.runs["deploy"][team]
        self._note_reached(team, run)
        self.board.set_status(team, TeamStatus.SETTLING)
        mine = [t for t in result.tasks_unserved if self.board.owner.get(t) == team]
        if mine:
            reasons = "; ".join(f"{t}: {result.unserved_reasons.get(t, 'not reached')}" for t in mine)
            await self.handovers.place(
                self._task_objects(run, mine), team, f"{team} could not serve them ({reasons})"
            )
        while True:
            board = run.executor.board if run.executor is not None else None
            extra = [t for t in entry.received if board is not None and t.id not in board.entries]
            if extra and not entry.lost:
                self.board.set_status(team, TeamStatus.DEPLOYING)
                return extra
            if self.board.settled():
                if not self._stop_lost_teams():  # a lost team's run ends first: it may hand tasks over
                    entry.finished = True
                    return []
            self.board.changed.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.board.changed.wait(), 1.0)

    async def _watch_carriers(self) -> None:
        """A deploying team whose carrier stays lost longer than ``links.reassign_after`` hands its
        unlaunched tasks to the other teams."""
        after = self.mission.links.reassign_after
        while True:
            await asyncio.sleep(WATCH_EVERY)
            for cid, entry in self.board.teams.items():
                run = self.runs.get("deploy", {}).get(cid)
                if run is None or run.fleet is None or entry.lost or entry.status != TeamStatus.DEPLOYING:
                    continue
                if not run.fleet.carrier.lost:
                    entry.lost_since = None
                    continue
                now = self.clock()  # mission seconds, like the heartbeat timeout
                entry.lost_since = entry.lost_since or now
                if now - entry.lost_since >= after:
                    entry.lost = True
                    await self.handovers.carrier_lost(cid, run, after)
            self._stop_lost_teams()

    def _stop_lost_teams(self) -> bool:
        """A team whose carrier is lost is not waited for once every other team has finished
        deploying: its run stops (its airborne rovers hold where they are, to be collected by the
        others) and the tasks it had not reached go to the teams that can take them. True while
        such a run is still ending."""
        if not self.board.settled():
            return False
        ending = False
        for cid, entry in self.board.teams.items():
            flying = self.flying.get(cid)
            if not (entry.lost and entry.status in ACTIVE):
                continue
            ending = True
            if flying is not None and not flying.done() and cid not in self._stopped:
                self._stopped.add(cid)
                self.journal.write(
                    Ev.TEAM,
                    team=cid,
                    phase="deploy",
                    status="stopped",
                    text=f"{cid}: carrier lost and every other team done: its run stops",
                )
                flying.cancel()
        return ending

    def _note_reached(self, cid: str, run: TeamRun) -> None:
        for tid, t in run.reached_at.items():
            if self.board.owner.get(tid) == cid:
                self.board.reached.setdefault(tid, (cid, t))
        self.board.touch()

    @staticmethod
    def _task_objects(run: TeamRun, ids: list[str]) -> list[Task]:
        entries = run.executor.board.entries if run.executor is not None else {}
        by_id = {t.id: t for t in run.mission.tasks}
        return [entries[t].task if t in entries else by_id[t] for t in ids if t in entries or t in by_id]

    # ============================================================================== dwell
    async def _dwell(self) -> None:
        """Every team's rovers stay on task; they are watched meanwhile as one team's are (their link
        lost or back, geofence breaches, batteries at the reserve: :meth:`_watch_dwell`)."""
        wait = self.mission.dwell if self.opts.dwell is None else self.opts.dwell
        self.dwell_planned = wait
        left = self.resume.dwell_left(wait) if self.resume is not None else wait
        if left < wait:
            self.journal.write(Ev.DWELL, text=f"every team dwells the {left:g} s left of {wait:g} s on task")
        else:
            self.journal.write(Ev.DWELL, text=f"every team dwells {wait:g} s on task")
        t0 = self.clock() - (wait - left)
        unlisten = self._listen_to_rovers()
        try:
            async with asyncio.timeout(wait / max(self.scale, 1e-9) + 60.0):
                while self.clock() - t0 < wait:
                    self._watch_dwell()
                    await asyncio.sleep(CLOCK_STEP)
        finally:
            unlisten()
        self.dwell_flown = self.clock() - t0

    def _listen_to_rovers(self) -> Callable[[], None]:
        """Tell every rover's own events while no team's run is flying (the dwell)."""
        assert self.fleet is not None
        removers = [v.add_listener(lambda ev: tell_vehicle_event(ev, self.emit, self.journal.write))
                    for v in self.fleet.rovers.values()]

        def unlisten() -> None:
            for remove in removers:
                remove()

        return unlisten

    def _watch_dwell(self) -> None:
        """A rover on task whose battery reaches the reserve is told once."""
        assert self.fleet is not None
        reserve = self.mission.rovers.reserve
        for rid, v in self.fleet.rovers.items():
            pct = v.battery_pct
            if pct is not None and pct / 100.0 <= reserve and rid not in self._low:
                self._low.add(rid)
                self.emit(Ev.BATTERY_LOW, battery_low_text(rid, pct), rid, battery_pct=pct)

    # ============================================================================== collection
    async def _collect(self) -> None:
        resume = self.resume
        if resume is not None:  # shared again from the live fleet: rovers already on a deck stay there
            ids = ([cr.id for cr in self.mission.collection or ()] if self.command == "collect"
                   else [*resume.launched(), *self._launched()])
            field = await self._rovers_in_the_field(ids)
            live = dataclasses.replace(self.live_mission(), collection=field)
            out = {cr.id for cr in field} | set(self.left)  # launched, found on a deck: loaded before
            self.loaded_before += [r for r in dict.fromkeys(ids) if r not in out and
                                   r not in self.loaded_before]
        elif self.command == "collect":
            live = self.live_mission()
        else:
            live = dataclasses.replace(self.live_mission(), collection=await self._rovers_in_the_field())
        if not live.collection:
            self.journal.write(Ev.NOTHING_TO_COLLECT, text="no rover in the field to collect")
            return
        plan = await self._share("collect", live)
        shares = {t.carrier: [leg.rover for leg in t.plan.legs()] for t in plan.teams}
        self.views = team_views(self.opts.view, [cid for cid, rovers in shares.items() if rovers])
        # a scenario's collection section (its batteries are pinned); a resumed one is the live fleet's
        keep = self.command == "collect" and resume is None
        runs = {}
        for cid, rovers in shares.items():
            if not rovers:
                continue
            own = team_mission(live, cid, tasks=(), rovers=rovers)
            own = dataclasses.replace(own, mqtt=None, collection=own.collection if keep else None)
            opts = self._team_opts(cid, "collect", rovers, resume=self._collect_resumption(cid))
            runs[cid] = team_crew(own, "collect", opts, cid, None, self.t0).flight
            self.board.set_status(cid, TeamStatus.COLLECTING)
        self.runs["collect"] = runs
        await self._fly_all("collect", runs, self._collect_ended)

    async def _collect_ended(self, cid: str, run: TeamRun, outcome: RunOutcome) -> None:
        self.board.set_status(cid, TeamStatus.DONE if outcome.exit_code == EXIT_OK else TeamStatus.FAILED)

    def _collect_resumption(self, cid: str) -> Resumption | None:
        """A resumed run's team collection whose records exist goes on in them (its journal
        appended to, reconciled with the live fleet) with a new plan of its new share."""
        res = self.resume.collect.get(cid) if self.resume is not None else None
        if res is None:
            return None
        return dataclasses.replace(res, started={}, planned={}, loaded={}, intents={})

    def _launched(self) -> list[str]:
        """Every rover this run's team deployments launched."""
        return [
            r
            for run in self.runs.get("deploy", {}).values()
            for r in (run.results["deploy"].launched if "deploy" in run.results else [])
        ]

    async def _rovers_in_the_field(self, launched: list[str] | None = None) -> tuple[CollectRover, ...]:
        """Every rover a team launched (``launched``: those given) that is not on a deck now
        (``self.left``: those that cannot be collected, with why)."""
        assert self.fleet is not None
        launched = self._launched() if launched is None else launched
        before = set(self.left)
        crs = await rovers_in_the_field(self.mission, self.fleet, launched, self.left)
        for rid in self.left.keys() - before:
            self.journal.write(
                Ev.ROVER_UNREACHABLE, vehicle=rid, text=f"{rid}: {self.left[rid]}; not collected"
            )
        return crs

    # ============================================================================== the teams' runs
    def live_mission(self) -> Mission:
        """The mission with every carrier where its telemetry puts it now (the sharing plans from there)."""
        return live_mission(self.mission, self.fleet)

    def _team_mission(self, cid: str, tasks: list[str]) -> Mission:
        return dataclasses.replace(team_mission(self.mission, cid, tasks=tasks), mqtt=None)

    def _team_opts(self, cid: str, phase: str, rovers: list[str] | None = None,
                   resume: Resumption | None = None) -> RunOptions:
        o = self.opts
        assert self.fleet is not None
        ids = tuple(rovers) if rovers is not None else self.board.teams[cid].rovers
        return RunOptions(
            speedup=o.speedup,
            planner=o.planner,
            dwell=o.dwell,
            run_dir=self.journal.dir / "teams" / cid / phase,
            view=self.views[cid],
            connect_timeout=o.connect_timeout,
            endpoints=self.endpoints,
            sim=self.sim,
            clock_speedup=o.clock_speedup if self.sim is None else None,
            vehicle_clock=self.session.vehicle_clock,  # one mission clock for every team
            require_all=o.require_all,
            force=o.force,
            confirm=self._confirm(),
            fleet=self.fleet.team(cid, ids),
            bus=self.buses.of(cid),
            resume=resume,
        )

    def _confirm(self) -> Callable[[list[str]], bool] | None:
        ask = self.opts.confirm
        if ask is None:
            return None

        def one_at_a_time(lines: list[str]) -> bool:  # the teams ask in turn on the one terminal
            with self._confirm_lock:
                return ask(lines)

        return one_at_a_time

    async def _share(self, phase: str, mission: Mission) -> TeamsPlan:
        from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS

        name = self.opts.planner or mission.planner_for(phase)
        planner = (DEPLOY_PLANNERS if phase == "deploy" else COLLECT_PLANNERS)[name]
        problem = teams_problem(mission, phase)
        try:
            plan = await asyncio.to_thread(share_teams, problem, planner, name)
        except Exception as exc:  # noqa: BLE001 - a PlanningError or a planner's ValueError
            raise ExecutionError(f"cannot share the {phase} between the teams: {exc}") from None
        self.plans[phase] = plan
        await asyncio.to_thread(
            self.journal.write_json,
            "plan.json" if phase == "deploy" or self.command == "collect" else "plan-collect.json",
            plan.to_json(),
        )
        shares = {
            t.carrier: [leg.task if phase == "deploy" else leg.rover for leg in t.plan.legs()]
            for t in plan.teams
        }
        self.buses.start_teams({k: [x for x in v if x is not None] for k, v in shares.items()})  # first only
        self.journal.write(
            Ev.TEAMS_PLAN,
            phase=phase,
            makespan=plan.makespan,
            allocation=plan.allocation,
            shares=shares,
            makespans={t.carrier: t.plan.makespan for t in plan.teams},
        )
        return plan

    async def _fly_all(
        self, phase: str, runs: dict[str, TeamRun], ended: Callable[[str, TeamRun, RunOutcome], Any]
    ) -> None:
        """Fly every team's run concurrently; a cancellation reaches every one (each holds its
        airborne rovers and writes its records) before it goes on."""
        outcomes = self.outcomes.setdefault(phase, {})

        async def one(cid: str, run: TeamRun) -> None:
            self.journal.write(Ev.TEAM, team=cid, phase=phase, status="started", run_dir=str(run.journal.dir))
            flying = self.flying[cid] = asyncio.create_task(run.crew.fly(), name=f"team {cid} {phase} run")
            try:
                outcome = await flying
            except asyncio.CancelledError:
                task = asyncio.current_task()
                if task is not None and task.cancelling():
                    flying.cancel()  # the run of every team is cancelled: so is this team's
                    raise
                outcome = RunOutcome(EXIT_INTERRUPTED, {"result": "interrupted"}, run.journal.dir, None)
            except Exception as exc:  # noqa: BLE001 - a fault in one team's run must not stop the others
                log.exception("team %s: its run failed", cid)
                outcome = RunOutcome(
                    EXIT_FAILED, {"result": "incomplete"}, run.journal.dir, f"{cid}: {exc!r}"
                )
            outcomes[cid] = outcome
            self.journal.write(
                Ev.TEAM,
                team=cid,
                phase=phase,
                status="ended",
                result=outcome.summary["result"],
                error=outcome.error,
            )
            await ended(cid, run, outcome)

        tasks = [asyncio.create_task(one(cid, run), name=f"team {cid} {phase}") for cid, run in runs.items()]
        try:
            await asyncio.gather(*tasks)
        except asyncio.CancelledError:  # gather cancelled every team's run: each holds and writes its records
            await asyncio.wait(tasks, timeout=60.0)
            raise
        except BaseException:
            for t in tasks:
                t.cancel()
            await asyncio.wait(tasks, timeout=60.0)
            raise

    # ============================================================================== the way out
    def _bus_finals(self, summary: dict[str, Any]) -> tuple[str, dict[str, str]]:
        """The final status of the run's bus and of each team's (``done``, ``failed``, ``interrupted``)."""
        if self.interrupted:
            return "interrupted", {}
        err = self.error is not None
        failed = {cid for cid, e in self.board.teams.items()
                  if e.status == TeamStatus.FAILED or (err and e.status != TeamStatus.DONE)}
        teams = {cid: "failed" if cid in failed else "done" for cid in self.board.teams}
        return ("done" if summary["result"] == "complete" else "failed"), teams

    async def end(self) -> dict[str, Any]:
        summary = self.summary = teams_summary(self)
        mqtt = self.buses.stats()
        if mqtt is not None:
            summary["mqtt"] = mqtt
        return summary

    async def close_bus(self) -> None:
        await self.buses.aclose(*self._bus_finals(self.summary))


__all__ = ["TeamsFlight"]
