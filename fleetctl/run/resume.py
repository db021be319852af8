"""``fleetctl resume --run DIR``: finish a run whose controller died.

1. :func:`load_resumption` reads the run folder: the journal (write-ahead, so it says what was
   commanded up to the crash) and the saved mission copy, refuses what does not match (another
   mission, a run already over, the embedded simulated fleet, which died with the controller),
   and replays the journal into a :class:`~fleetctl.run.task_board.TaskBoard` (tasks reached,
   rovers launched and where to, refused, unusable) and the rovers already loaded.
2. After connecting, :meth:`Resumption.reconcile` checks the journal against live telemetry:
   a rover the journal sent to a task is still flying there, already holds on it, has landed
   elsewhere or is lost; a rover the crash caught between its ``launch`` record and its
   lift-off is flying if it is armed or airborne.
3. The runner then finishes the interrupted phase (and, for a ``run``, what follows) from the
   current state with the same phases, appending to the same journal.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fleetctl.journal import JOURNAL_NAME, MISSION_COPY, JournalError, read_journal
from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.mission import Mission, MissionError, load_mission
from fleetctl.mission.teams import mission_teams
from fleetctl.run.collect import ResumedCollect
from fleetctl.run.deploy import HOLD_SPEED, REACH_RADIUS, ResumedDeploy
from fleetctl.run.kinds import PHASES, Ev, phases_of
from fleetctl.run.operation.resume import OperationReplay, reconcile_operation, replay_operation
from fleetctl.run.results import PhaseResult
from fleetctl.run.sim import mission_uses_sim
from fleetctl.run.state import FleetState, on_deck
from fleetctl.run.task_board import TaskBoard, TaskStatus
from planners.core.problem import Task

Disarm = Callable[[Vehicle], Awaitable[None]]
SETTLE_TIMEOUT = 5.0  # wall s to wait for every vehicle's position before reconciling


class ResumeError(Exception):
    """The run folder cannot be resumed; the message says why and what to do."""


@dataclass
class Resumption:
    """An interrupted run, as the journal tells it (see the module docstring)."""

    run_dir: Path
    command: str  # the interrupted command: deploy | collect | run
    mission: Mission
    board: TaskBoard
    phase: str  # the phase that was interrupted
    scale: float  # mission seconds per wall second of the interrupted run
    started: dict[str, float] = field(default_factory=dict)  # phase -> unix time its carrier started
    planned: dict[str, float] = field(default_factory=dict)  # phase -> first plan's makespan
    loaded: dict[str, float] = field(default_factory=dict)  # rover -> loaded at (collect)
    intents: dict[str, str] = field(default_factory=dict)  # rover -> task of a launch not confirmed
    dwell_started: float | None = None  # unix time
    options: dict[str, Any] = field(default_factory=dict)  # planner, dwell of the interrupted run
    found: dict[str, Any] = field(default_factory=dict)
    operation: OperationReplay | None = None  # a long operation's story (fleetctl.run.operation.resume)

    # -- for the runner ----------------------------------------------------------------------------
    def finished_results(self) -> dict[str, PhaseResult]:
        """Results of the phases over before the crash (a ``run`` past its deployment)."""
        if self.command == "run" and self.phase in ("dwell", "collect"):
            return {"deploy": self.deploy_result()}
        return {}

    def phases_left(self, command: str) -> list[str]:
        order = phases_of(command)
        return order[order.index(self.phase) :] if self.phase in order else order

    def _elapsed(self, phase: str) -> float:
        t = self.started.get(phase)
        return 0.0 if t is None else max(0.0, (time.time() - t) * self.scale)

    @property
    def deploy(self) -> ResumedDeploy | None:
        if self.phase != "deploy" or "deploy" not in self.started:
            return None
        return ResumedDeploy(self._elapsed("deploy"), self.planned.get("deploy"))

    @property
    def collect(self) -> ResumedCollect | None:
        if self.phase != "collect" or "collect" not in self.started:
            return None
        return ResumedCollect(self._elapsed("collect"), self.planned.get("collect"), dict(self.loaded))

    def dwell_left(self, wait: float) -> float:
        if self.phase != "dwell" or self.dwell_started is None:
            return wait
        return max(0.0, wait - (time.time() - self.dwell_started) * self.scale)

    def collect_ids(self) -> list[str] | None:
        if self.command == "collect" and not self.board.launched:
            return None  # a collect run: every rover in the field
        return [r for r in self.board.launched if r not in self.loaded]

    def record(self) -> dict[str, Any]:
        return {"command": self.command, "phase": self.phase, "found": self.found}

    # -- against the live fleet --------------------------------------------------------------------
    def _on_deck(self, fleet: Fleet, v: Vehicle) -> bool:
        return on_deck(v.enu, fleet.carrier.enu, v.on_ground, v.ground_speed, v.height,
                       self.mission.carrier.deck_height)

    async def reconcile(self, fleet: Fleet, state: FleetState, disarm: Disarm) -> None:
        """Check the journal against live telemetry (see the module docstring). Tasks found
        reached are journalled as such; a rover armed on the deck by a launch the crash cut
        short is disarmed (``disarm``) and may fly again."""
        await asyncio.gather(*(_settle(v) for v in fleet.vehicles.values() if v.connected))
        if self.operation is not None:
            self.found = await reconcile_operation(self.operation, fleet, state, disarm,
                                                   lambda v: self._on_deck(fleet, v), time.time())
            return
        found: dict[str, Any] = {"reached": self.board.with_status(TaskStatus.REACHED), "flying": {},
                                 "holding_on_task": [], "landed_elsewhere": [], "back_on_deck": [],
                                 "lost": [], "loaded": sorted(self.loaded)}
        for rid, task in list(self.intents.items()):  # a launch record without its lift-off
            v = fleet.rovers.get(rid)
            if v is not None and v.connected and _airborne(v) and self.board.is_pooled(task):
                self.board.fly(task, rid)
        if self.phase == "deploy":
            self._reconcile_flying(fleet, state, found)
        for rid in self.intents:
            v = fleet.rovers.get(rid)
            if v is not None and v.connected and v.armed and self._on_deck(fleet, v):
                await disarm(v)
                found["back_on_deck"].append(rid)
        c = fleet.carrier
        found["carrier"] = {"position": [round(x, 2) for x in c.enu] if c.enu else None, "armed": c.armed,
                            "mode": c.mode, "mission_item": c.mission_current}
        self.found = found

    def _reconcile_flying(self, fleet: Fleet, state: FleetState, found: dict[str, Any]) -> None:
        board = self.board
        for task, rid in board.flying().items():
            v = fleet.rovers.get(rid)
            target = board.entries[task].task.position
            if v is None or not v.connected or v.lost:
                board.give_back(task, f"its rover {rid} did not answer after the controller restarted")
                found["lost"].append(rid)
            elif v.enu is not None and math.dist(v.enu, target) <= REACH_RADIUS and \
                    (v.ground_speed or 0.0) < HOLD_SPEED:
                flown = self._elapsed("deploy")
                board.reach(task, flown)
                found["holding_on_task"].append(rid)
                state.event(Ev.TASK_REACHED, f"{rid}: reached {task} (found holding on it on resume)", rid,
                            task=task, flown=flown)
            elif self._on_deck(fleet, v):  # the crash caught it before it took off
                board.give_back(task, f"its rover {rid} was still on the deck")
                board.unlaunch(rid)
                self.intents[rid] = task
                found["back_on_deck"].append(rid)
            elif not _airborne(v):
                board.give_back(task, f"its rover {rid} was found on the ground away from it")
                board.rejoined.append(rid)
                found["landed_elsewhere"].append(rid)
            else:
                found["flying"][rid] = task

    def deploy_result(self) -> PhaseResult:
        """The deployment as the journal tells it (a ``run`` interrupted after it)."""
        b = self.board
        reached = b.reached()
        order = list(b.entries)
        res = PhaseResult("deploy", planned=self.planned.get("deploy"))
        res.tasks_reached = [t for t in order if t in reached]
        res.tasks_unserved = [t for t in order if t not in reached]
        res.unserved_reasons = {t: r for t, r in b.unserved_reasons().items() if t in res.tasks_unserved}
        res.tasks_all, res.launched = order, list(b.launched)
        res.assignment, res.substitutions = dict(b.assignment), list(b.substitutions)
        res.tasks_added, res.tasks_removed, res.rejoined = list(b.added), list(b.removed), list(b.rejoined)
        res.complete = not res.tasks_unserved
        res.flown = (max(reached.values()) if reached else 0.0) if res.complete else None
        return res


async def _settle(v: Vehicle) -> None:
    with contextlib.suppress(TimeoutError):
        await v.wait_until(lambda v: v.enu is not None and v.landed_state is not None, SETTLE_TIMEOUT,
                           "telemetry")


def _airborne(v: Vehicle) -> bool:
    return v.on_ground is False or (v.height or 0.0) > 0.3


# ================================================================================== the folder
def load_resumption(run_dir: str | Path, mission_file: str | Path | None = None) -> Resumption:
    """Read a run folder (see the module docstring); :class:`ResumeError` when it cannot be resumed."""
    d, records, run, mission = read_run(run_dir, mission_file)
    return resumption_of(d, records, str(run["command"]), mission, float(run.get("speedup") or 1.0),
                         {"planner": run.get("planner"), "dwell": run.get("dwell")})


Records = list[dict[str, Any]]


def read_run(run_dir: str | Path,
             mission_file: str | Path | None = None) -> tuple[Path, Records, dict[str, Any], Mission]:
    """The run folder ``run_dir``, its journal's records, its ``run`` record and the mission it
    flew; :class:`ResumeError` when it cannot be resumed (no journal, another mission file, the
    embedded simulated fleet, a run that completed, vehicles that are not the mission's)."""
    d = Path(run_dir)
    if not (d / JOURNAL_NAME).is_file():
        raise ResumeError(
            f"{d}: no {JOURNAL_NAME} here; give the run folder printed when the run "
            "started (runs/<mission>-<timestamp>)"
        )
    records = read_records(d / JOURNAL_NAME)
    run = next((r for r in records if r["kind"] == Ev.RUN), None)
    if run is None or run.get("command") not in ("deploy", "collect", "run"):
        raise ResumeError(f"{d / JOURNAL_NAME}: no 'run' record: not the journal of a deploy, collect or run")
    mission = _mission(d, run, mission_file)
    if mission_uses_sim(mission):
        raise ResumeError(
            f"{d}: the run flew the embedded simulated fleet (connection: sim), which died "
            "with the controller; there is no fleet left to resume. Fly it again, or serve "
            "the fleet with 'fleetctl sim' and fly it over real URLs to be able to resume"
        )
    last = next((r for r in reversed(records) if r["kind"] == Ev.SUMMARY), None)
    if last is not None and last.get("result") == "complete":
        raise ResumeError(f"{d}: this run completed ({last.get('phase')}); there is nothing to resume")
    _check_vehicles(d, records, mission)
    return d, records, run, mission


def read_records(path: Path) -> list[dict[str, Any]]:
    """A journal's records (:class:`ResumeError` when it cannot be read)."""
    try:
        return read_journal(path)
    except JournalError as exc:
        raise ResumeError(str(exc)) from None


def resumption_of(d: Path, records: list[dict[str, Any]], command: str, mission: Mission, scale: float,
                  options: dict[str, Any] | None = None) -> Resumption:
    """The :class:`Resumption` of the run of ``command`` whose folder is ``d`` and journal
    ``records``, flying ``mission`` (a run of several teams builds one per team's folder)."""
    res = Resumption(d, command, mission, TaskBoard.of(mission.tasks),
                     "collect" if command == "collect" else "deploy", scale, options=dict(options or {}))
    _replay(res, records)
    if mission.operation:
        res.operation = replay_operation(records, mission, scale)
    return res


def _mission(d: Path, run: dict[str, Any], mission_file: str | Path | None) -> Mission:
    copy = d / MISSION_COPY
    if not copy.is_file():
        raise ResumeError(f"{d}: no {MISSION_COPY} (the copy of the mission the run flew)")
    saved = copy.read_bytes()
    if mission_file is not None:
        if Path(mission_file).read_bytes() != saved:
            raise ResumeError(
                f"{mission_file} is not the mission this run flew ({copy} differs); resume "
                "without --mission to use the saved copy"
            )
        path = Path(mission_file)
    else:  # the original file when unchanged (live edits keep working), else the copy
        orig = Path(str(run.get("file") or ""))
        path = orig if orig.is_file() and orig.read_bytes() == saved else copy
    try:
        return load_mission(path)
    except MissionError as exc:
        raise ResumeError(str(exc)) from None


def _check_vehicles(d: Path, records: list[dict[str, Any]], mission: Mission) -> None:
    sysids = {t.carrier.id: t.carrier.sysid for t in mission_teams(mission)}
    sysids |= {u.id: u.sysid for u in mission.rovers.units}
    for r in records:
        if r["kind"] != Ev.CONNECTED:
            continue
        vid = r.get("vehicle")
        if vid not in sysids or r.get("sysid") != sysids[vid]:
            raise ResumeError(
                f"{d / JOURNAL_NAME}: the journal's vehicle {vid!r} (sysid {r.get('sysid')}) is "
                f"not in the mission {mission.name!r}; the journal and the mission do not match"
            )


def _replay(res: Resumption, records: list[dict[str, Any]]) -> None:
    """Rebuild the board and the phases' clocks from the journal's records, in order."""
    board, phase = res.board, res.phase
    for r in records:
        kind, rid, task = r["kind"], r.get("vehicle"), r.get("task")
        if kind == Ev.PHASE and r.get("phase") == "operation":
            res.phase = "operation"
        elif kind == Ev.PHASE and r.get("phase") in PHASES:
            phase = res.phase = str(r["phase"])
            if phase == "dwell":
                res.dwell_started = float(r["t"])
        elif kind == Ev.PLAN and phase not in res.planned and isinstance(r.get("plan"), dict):
            res.planned[phase] = float(r["plan"].get("makespan") or 0.0)
        elif kind in (Ev.CARRIER_STARTED, Ev.COLLECTION_STARTED) and phase not in res.started:
            res.started[phase] = float(r["t"])
        elif kind == Ev.TASKS_CHANGED:
            _replay_task_change(board, r)
        else:
            _replay_rover(res, kind, rid, task, r)


def _replay_rover(res: Resumption, kind: str, rid: Any, task: Any, r: dict[str, Any]) -> None:
    board = res.board
    known = isinstance(task, str) and task in board.entries
    if kind == Ev.LAUNCH and isinstance(rid, str) and known:
        res.intents[rid] = task
    elif kind == Ev.ROVER_LAUNCHED and isinstance(rid, str) and known:
        res.intents.pop(rid, None)
        board.fly(task, rid)
    elif kind == Ev.TASK_REACHED and known:
        board.reach(task, float(r.get("flown") or 0.0))
    elif kind == Ev.TASK_RETURNED and known:
        board.give_back(task, str(r.get("text") or "returned"))
        if isinstance(rid, str) and rid not in board.rejoined:
            board.rejoined.append(rid)
    elif kind in (Ev.TASK_TIMEOUT, Ev.TASK_UNSERVED) and known:
        board.unserve(task, str(r.get("text") or "not reached"))
    elif kind == Ev.ROVER_REFUSED and isinstance(rid, str):
        board.refused.add(rid)
    elif kind == Ev.ROVER_UNUSABLE and isinstance(rid, str):
        board.unusable.add(rid)
    elif kind == Ev.ROVER_LOADED and isinstance(rid, str):
        res.loaded[rid] = float(r.get("flown") or 0.0)


def _replay_task_change(board: TaskBoard, r: dict[str, Any]) -> None:
    for tid in r.get("remove") or []:
        if tid in board.entries:
            board.remove(tid)
    for t in r.get("added") or []:
        if isinstance(t, dict) and isinstance(t.get("id"), str) and t["id"] not in board.entries:
            p = t.get("position") or [0.0, 0.0, 0.0]
            board.add(Task(t["id"], (float(p[0]), float(p[1]), float(p[2]))))


__all__ = ["ResumeError", "Resumption", "load_resumption", "read_records", "read_run", "resumption_of"]
