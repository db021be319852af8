"""Resuming an interrupted operation (``fleetctl resume --run DIR``; docs/operations.md, "Resuming").

1. :func:`replay_operation` reads the journal into an :class:`OperationReplay`: the operation's
   tasks (with the changes flown), each task's work (who, started, done, in operation seconds),
   every sortie launched and where it stood (``sortie_launched`` carries its mission's work items),
   the swaps, the rovers lost, and the launches written ahead whose sortie never took off.
2. :func:`reconcile_operation` checks it against live telemetry: a sortie's rover that does not
   answer is lost (its work not done is done again by others); one found on the deck is back; one
   in the air goes on with its sortie, and its firmware's current mission item says which of its
   tasks it worked while the controller was down (done: its timing item passed; being worked: its
   arrival passed). A rover armed on the deck by a launch the crash cut short is disarmed; one
   found in the air from such a launch (its sortie's work items never journalled) is called back.
3. The operation phase (:meth:`~fleetctl.run.operation.phase.OperationPhase.resume`) then replans
   from the live state and flies on.
"""

from __future__ import annotations

import contextlib
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.sortie import WorkItems
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.mission import Mission
from fleetctl.run.kinds import Ev
from fleetctl.run.operation.board import OperationBoard, SortieEntry, SortieStatus, TaskWorkState
from fleetctl.run.operation.sortie import item_passed, landed_near
from fleetctl.run.state import FleetState
from planners.operations import OpTask

Records = list[dict[str, Any]]
Disarm = Callable[[Vehicle], Awaitable[None]]
OnDeck = Callable[[Vehicle], bool]
CURRENT_WAIT = 5.0  # wall s for a rover in the air to report its current mission item
OUT = (SortieStatus.FLYING, SortieStatus.RETURNING)


@dataclass
class OperationReplay:
    """An interrupted operation as its journal tells it (times in operation seconds)."""

    tasks: dict[str, OpTask]  # every task of the operation now (changes applied)
    scale: float  # mission seconds per wall second of the interrupted run
    board: OperationBoard = field(default_factory=OperationBoard)
    work: dict[int, tuple[WorkItems, ...]] = field(default_factory=dict)  # sortie -> its mission's work items
    started_unix: float | None = None  # when the carrier started the operation's first route
    planned: float | None = None  # the first plan's makespan
    replans: int = 0
    added: list[str] = field(default_factory=list)
    removed: list[str] = field(default_factory=list)
    launching: dict[str, int] = field(default_factory=dict)  # rover -> stop of a launch not journalled flown
    in_air: dict[str, SortieEntry] = field(default_factory=dict)  # filled by reconcile_operation

    def op_time(self, t_unix: float) -> float:
        return 0.0 if self.started_unix is None else (t_unix - self.started_unix) * self.scale

    def elapsed(self, now_unix: float) -> float:
        return max(self.op_time(now_unix), 0.0)

    def entry(self, index: int) -> SortieEntry | None:
        return next((s for s in self.board.sorties if s.index == index), None)

    def out(self) -> list[SortieEntry]:
        """The sorties launched and not back, lost or failed."""
        return [s for s in self.board.sorties if s.status in OUT]


# ================================================================================== the journal
def replay_operation(records: Records, mission: Mission, scale: float) -> OperationReplay:
    """The journal's story of an operation (see the module docstring)."""
    rep = OperationReplay({t.id: t for t in mission.operation_problem().tasks}, scale)
    rep.board.tasks = {t.id: TaskWorkState(t.duration) for t in rep.tasks.values()}
    for r in records:
        kind = r["kind"]
        if kind == Ev.CARRIER_STARTED and rep.started_unix is None:
            rep.started_unix = float(r["t"])
        elif kind == Ev.PLAN and r.get("plan") == "operation" and rep.planned is None:
            rep.planned = float(r.get("makespan") or 0.0)
        elif kind == Ev.REPLAN and "error" not in r:
            rep.replans = max(rep.replans, int(r.get("n") or 0))
        elif kind == Ev.TASKS_CHANGED:
            _replay_change(rep, r)
        else:
            _replay_sortie(rep, kind, r)
    return rep


def _replay_change(rep: OperationReplay, r: dict[str, Any]) -> None:
    for tid in r.get("remove") or []:
        if tid in rep.tasks:
            del rep.tasks[tid]
            rep.board.tasks.pop(tid, None)
            rep.removed.append(tid)
    for t in r.get("retimed") or []:
        if isinstance(t, dict) and t.get("id") in rep.tasks:
            old = rep.tasks[t["id"]]
            rep.tasks[old.id] = OpTask(old.id, old.position, float(t.get("duration") or 0.0),
                                       t.get("work") == "ground")
            rep.board.tasks[old.id].duration = rep.tasks[old.id].duration
    for t in r.get("added") or []:
        if isinstance(t, dict) and isinstance(t.get("id"), str) and t["id"] not in rep.tasks:
            p = [float(x) for x in t.get("position") or (0.0, 0.0, 0.0)]
            task = OpTask(t["id"], (p[0], p[1], p[2]), float(t.get("duration") or 0.0),
                          t.get("work") == "ground")
            rep.tasks[task.id] = task
            rep.board.tasks[task.id] = TaskWorkState(task.duration)
            rep.added.append(task.id)


def _replay_sortie(rep: OperationReplay, kind: str, r: dict[str, Any]) -> None:
    rid, b = r.get("vehicle"), rep.board
    entry = rep.entry(int(r["sortie"])) if isinstance(r.get("sortie"), int) else None
    work = b.tasks.get(str(r.get("task")))
    if kind == Ev.LAUNCH and isinstance(rid, str):
        rep.launching[rid] = int(r.get("stop") or 0)
    elif kind == Ev.SORTIE_LAUNCHED and isinstance(rid, str) and entry is None:
        rep.launching.pop(rid, None)
        _launched(rep, rid, r)
    elif kind == Ev.TASK_STARTED and work is not None and work.done is None:
        work.rover, work.started = rid, rep.op_time(float(r["t"]))
        work.seen_start = r.get("found") is None  # (a start found on an earlier resume is a bound)
    elif kind == Ev.TASK_DONE and work is not None:
        work.rover, work.done = rid, rep.op_time(float(r["t"]))
    elif kind == Ev.SORTIE_CONTINUED and entry is not None:  # the sortie's mission is now this part
        rep.work[entry.index] = _work_items(r)
    elif kind == Ev.SORTIE_RETURNING and entry is not None:
        entry.status = SortieStatus.RETURNING
    elif kind == Ev.SORTIE_BACK and entry is not None:
        entry.status, entry.aboard = SortieStatus.ABOARD, rep.op_time(float(r["t"]))
    elif kind == Ev.SORTIE_LOST and entry is not None:
        _lose(rep, entry)
    elif kind == Ev.SORTIE_CALLED_BACK and entry is not None:
        dropped = [str(t) for t in r.get("tasks") or []]
        entry.tasks = [t for t in entry.tasks if t not in dropped]
        for t in dropped:
            w = rep.board.tasks.get(t)
            if w is not None and w.done is None:
                w.started = w.rover = None
    elif kind == Ev.BATTERY_SWAPPED and isinstance(rid, str):
        b.swaps.append((rid, float(r.get("done") or 0.0)))


def _launched(rep: OperationReplay, rid: str, r: dict[str, Any]) -> None:
    tasks = [str(t) for t in r.get("tasks") or []]
    entry = SortieEntry(int(r["sortie"]), rid, tasks, SortieStatus.FLYING, rep.op_time(float(r["t"])))
    rep.board.sorties.append(entry)
    rep.board.next_index = max(rep.board.next_index, entry.index + 1)
    rep.work[entry.index] = _work_items(r)


def _work_items(r: dict[str, Any]) -> tuple[WorkItems, ...]:
    """A record's ``work``: its mission's ``[task, arrive_seq, done_seq]`` per task."""
    return tuple(WorkItems(str(w[0]), int(w[1]), int(w[2])) for w in r.get("work") or [])


def _lose(rep: OperationReplay, entry: SortieEntry) -> None:
    """A lost rover's work is lost with it: its tasks not done are done again in full."""
    entry.status = SortieStatus.LOST
    if entry.rover not in rep.board.lost:
        rep.board.lost.append(entry.rover)
    for t in entry.tasks:
        w = rep.board.tasks.get(t)
        if w is not None and w.done is None:
            w.started = w.rover = None


# ================================================================================== the live fleet
async def reconcile_operation(rep: OperationReplay, fleet: Fleet, state: FleetState, disarm: Disarm,
                              on_deck: OnDeck, now_unix: float) -> dict[str, Any]:
    """Check the journal against live telemetry (see the module docstring); what was found."""
    found: dict[str, Any] = {"operation_s": round(rep.elapsed(now_unix), 3), "in_air": {}, "back_on_deck": [],
                             "lost": [], "done_while_down": [], "called_back": [], "disarmed": []}
    now = rep.elapsed(now_unix)
    for entry in rep.out():
        v = fleet.rovers.get(entry.rover)
        if v is None or not v.connected or v.lost:
            _lose(rep, entry)
            found["lost"].append(entry.rover)
            state.event(Ev.SORTIE_LOST, f"{entry.rover}: sortie {entry.index} lost (it did not answer after "
                        "the controller restarted)", entry.rover, sortie=entry.index,
                        tasks_left=_left(rep, entry),
                        reason="no answer on resume")
        elif on_deck(v):
            entry.status, entry.aboard = SortieStatus.ABOARD, now
            found["back_on_deck"].append(entry.rover)
            state.event(Ev.SORTIE_BACK, f"{entry.rover}: back on the deck from sortie {entry.index} (found "
                        "on resume)", entry.rover, sortie=entry.index, battery_pct=v.battery_pct,
                        found="on resume")
            _lose_work(rep, entry)
        else:
            await _current(v)
            _in_the_air(rep, entry, v, state, now, found)
            rep.in_air[entry.rover] = entry
            found["in_air"][entry.rover] = _left(rep, entry)
    await _unfinished_launches(rep, fleet, state, disarm, on_deck, found, now)
    return found


def _left(rep: OperationReplay, entry: SortieEntry) -> list[str]:
    return [t for t in entry.tasks if t in rep.board.tasks and rep.board.tasks[t].done is None]


def _lose_work(rep: OperationReplay, entry: SortieEntry) -> None:
    """A rover back on the deck with tasks not done: they are done again in full by a later sortie."""
    for t in entry.tasks:
        w = rep.board.tasks.get(t)
        if w is not None and w.done is None:
            w.started = w.rover = None


async def _current(v: Vehicle) -> None:
    with contextlib.suppress(TimeoutError):
        await v.wait_until(lambda v: v.mission_current is not None, CURRENT_WAIT, "current mission item")


def _in_the_air(rep: OperationReplay, entry: SortieEntry, v: Vehicle, state: FleetState, now: float,
                found: dict[str, Any]) -> None:
    """What a rover in the air did while the controller was down, from its current mission item
    (its sortie's mission: a sortie journalled returning flies its way back, nothing to infer)."""
    if entry.status is SortieStatus.RETURNING:
        return
    parts = rep.work.get(entry.index, ())
    last = rep.tasks.get(parts[-1].task) if parts else None
    landed = last is not None and parts[-1].done_seq < 0 and landed_near(v, last.position)
    for w in parts:
        work = rep.board.tasks.get(w.task)
        if work is None or work.done is not None:
            continue
        if landed and w is parts[-1]:  # on the ground at the task its mission ended at: working there
            if work.started is None or work.rover != entry.rover:
                work.rover, work.started, work.seen_start = entry.rover, now, False
                state.event(Ev.TASK_STARTED, f"{entry.rover}: landed at task {w.task} (found working on "
                            "resume)", entry.rover, task=w.task, sortie=entry.index, found="on resume")
            continue
        if (w.done_seq >= 0 and item_passed(v, w.done_seq)) or landed:  # (landed: its mission is past it)
            work.rover, work.done = entry.rover, now
            work.started = now if work.started is None else work.started
            found["done_while_down"].append(w.task)
            state.event(Ev.TASK_DONE, f"{entry.rover}: task {w.task} done while the controller was down (its "
                        "timing item passed, found on resume)", entry.rover, task=w.task, sortie=entry.index,
                        worked=None, duration=work.duration, found="on resume")
        elif item_passed(v, w.arrive_seq) and (work.started is None or work.rover != entry.rover):
            work.rover, work.started, work.seen_start = entry.rover, now, False  # its start unknown
            state.event(Ev.TASK_STARTED, f"{entry.rover}: at task {w.task} (found working on resume)",
                        entry.rover, task=w.task, sortie=entry.index, found="on resume")


async def _unfinished_launches(rep: OperationReplay, fleet: Fleet, state: FleetState, disarm: Disarm,
                               on_deck: OnDeck, found: dict[str, Any], now: float) -> None:
    """Launches written ahead whose sortie was never journalled flown: the rover still on the
    deck is disarmed if armed; one in the air is called back (its work is not counted)."""
    for rid in sorted(rep.launching):
        v = fleet.rovers.get(rid)
        if v is None or not v.connected or v.lost:
            continue
        if on_deck(v):
            if v.armed:
                await disarm(v)
                found["disarmed"].append(rid)
            continue
        entry = rep.board.new_sortie(rid, [])
        entry.status, entry.launched = SortieStatus.FLYING, now
        rep.in_air[rid] = entry
        found["called_back"].append(rid)
        state.event(Ev.SORTIE_LAUNCHED, f"{rid}: found in the air from a launch the crash cut short; "
                    f"called back as sortie {entry.index}", rid, sortie=entry.index, tasks=[],
                    stop=rep.launching[rid], work=[], found="on resume")
    rep.launching.clear()


__all__ = ["OperationReplay", "reconcile_operation", "replay_operation"]
