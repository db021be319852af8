"""Tasks added or removed while an operation flies (the watched mission file, MQTT): applied at
the carrier's next stop, then the rest of the operation is replanned. An added task gets the work the
change gives it (its ``duration`` and ``work``, read by the mission loader from the edited file or the
MQTT message), else the running mission's (``Mission.task_work``: ``dwell`` and ``rovers.work``); a
kept task's work may change too (``retime``); a task a rover in the air still has is neither removed
nor changed (the change says so)."""

from __future__ import annotations

from collections.abc import Iterable

from fleetctl.run.context import RunContext
from fleetctl.run.kinds import Ev
from fleetctl.run.operation.board import OperationBoard, TaskWorkState
from fleetctl.run.supervisor import SupervisorEvent
from fleetctl.run.task_board import TaskBoard
from planners.operations import OpTask


class TaskChanges:
    """Applies task changes to the operation's tasks (see the module docstring)."""

    def __init__(self, ctx: RunContext, board: OperationBoard, tasks: dict[str, OpTask],
                 live: TaskBoard) -> None:
        self.ctx, self.board, self.tasks, self.live = ctx, board, tasks, live
        self.added: list[str] = []
        self.removed: list[str] = []

    def apply(self, ev: SupervisorEvent, flying: Iterable[str]) -> bool:
        """Apply one change (``flying``: tasks a rover in the air still has); True when the tasks changed."""
        busy = set(flying)
        kept = [t for t in ev.remove if t in busy]
        gone = [t for t in ev.remove if t in self.board.tasks and t not in busy]
        for tid in gone:
            del self.board.tasks[tid]
            self.tasks.pop(tid, None)
            if tid in self.live.entries:
                self.live.remove(tid)
            self.removed.append(tid)
        new = [t for t in ev.add if t.id not in self.board.tasks]
        for t in new:
            w = ev.work.get(t.id) or self.ctx.mission.task_work(t.id)
            self.tasks[t.id] = OpTask(t.id, t.position, w.duration, w.ground)
            self.board.tasks[t.id] = TaskWorkState(w.duration)
            self.live.add(t)
            self.added.append(t.id)
        retimed = self._retime(ev, busy)
        if kept:
            self.ctx.state.event(Ev.TASK_CHANGE_REJECTED, f"task change from {ev.source}: {', '.join(kept)} "
                                 f"kept: a rover in the air is working it", None, source=ev.source,
                                 reason="a rover in the air is working it", tasks=kept)
        if not (gone or new or retimed):
            return False
        ids = [t.id for t in new]
        text = (f"tasks changed by {ev.source}: added {', '.join(ids) or 'none'}, "
                f"removed {', '.join(gone) or 'none'}"
                + (f", work changed {', '.join(retimed)}" if retimed else ""))
        self.ctx.state.event(Ev.TASKS_CHANGED, text, None, add=ids, remove=gone, source=ev.source,
                             added=[self._json(t) for t in ids], retimed=[self._json(t) for t in retimed])
        return True

    def _retime(self, ev: SupervisorEvent, busy: set[str]) -> list[str]:
        """Kept tasks given a new duration or work mode: changed, unless a rover in the air has it
        (its firmware times the work it was given) or its work is done (both said); the changed ones."""
        changed, refused = [], {}
        for tid, w in ev.retime.items():
            state, task = self.board.tasks.get(tid), self.tasks.get(tid)
            if state is None or task is None or (task.duration, task.ground) == (w.duration, w.ground):
                continue
            if tid in busy or state.done is not None:
                refused[tid] = "a rover in the air has it" if tid in busy else "its work is done"
                continue
            self.tasks[tid] = OpTask(tid, task.position, w.duration, w.ground)
            state.duration, state.started, state.rover = w.duration, None, None
            changed.append(tid)
        for tid, why in refused.items():
            self.ctx.state.event(Ev.TASK_CHANGE_REJECTED, f"task change from {ev.source}: {tid}'s work "
                                 f"not changed: {why}", None, source=ev.source, reason=why, tasks=[tid])
        return changed

    def _json(self, tid: str) -> dict[str, object]:
        t = self.tasks[tid]
        return {"id": t.id, "position": list(t.position), "duration": t.duration,
                "work": "ground" if t.ground else "hover"}


__all__ = ["TaskChanges"]
